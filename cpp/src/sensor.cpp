// The sense stage of a simulation's step: each robot's force/torque sensor at its tool centre
// point (SensorOptions in simulation.hpp): the true wrench its end applies to the environment,
// seeded Gaussian noise in the sensor frame, a first-order low-pass filter.
#include <cmath>
#include <stdexcept>

#include "coopsim/simulation.hpp"
#include "internal.hpp"
#include "stages.hpp"

namespace coopsim {

void check_sensor_options(const SensorOptions& o) {
  const struct {
    const char* name;
    double value;
    const char* unit;
  } fields[] = {{"noise_force", o.noise_force, " N"},
                {"noise_moment", o.noise_moment, " N m"},
                {"time_constant", o.time_constant, " s"}};
  for (const auto& f : fields)
    if (!(f.value >= 0) || !std::isfinite(f.value))
      throw std::invalid_argument(std::string("sensor: ") + f.name + " must be finite and >= 0" + f.unit + ", got " +
                                  detail::num(f.value));
  if (o.seed < 0) throw std::invalid_argument("sensor: seed must be >= 0, got " + std::to_string(o.seed));
}

void Simulation::set_sensor(int i, const SensorOptions& options) {
  const Entry driving = enter_();  // one driver at a time
  check_sensor_options(options);
  RobotData& s = slot_(i);
  fresh_sensor_(i);  // a filter set now starts from the reading at this time
  edit_().robots[i].sensor = options;
  s.sensor.rng.seed(static_cast<std::uint64_t>(options.seed));
  s.sensor.normal.reset();
}

const RobotData::Sensor& Simulation::fresh_sensor_(int i) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  if (s.sensor.stale) stages::sense_robot(*model_, data_, i, true);
  return s.sensor;
}

Eigen::Isometry3d Simulation::sensor_pose(int i) const {
  const RobotData& s = slot_(i);
  const Robot& r = robot(i);
  Workspace ws;
  r.kinematics(s.state.q.data(), ws, false);
  return r.tool_pose(ws);
}

namespace stages {

void reset_sensor(const RobotModel& r, RobotData& s) {
  RobotData::Sensor& z = s.sensor;
  z.rng.seed(static_cast<std::uint64_t>(r.sensor.seed));
  z.normal.reset();
  z.noise.setZero();
  z.prev.setZero();
  z.true_clamp.setZero();
  z.true_world.setZero();
  z.clamp.setZero();
  z.world.setZero();
  z.at = -1;
  z.has_prev = false;
  z.stale = false;
}

// The sense stage at t_k. Run again at the same step (a second row after the applied inputs
// changed), it recomputes the true wrench with the noise drawn for this step and the filter's state
// before it: a step draws its noise once and advances the filter once.
void sense(const Model& m, Data& d) {
  for (int i = 0; i < static_cast<int>(d.robots.size()); ++i) sense_robot(m, d, i);
}

void sense_robot(const Model& m, Data& d, int i, bool now, bool framed) {
  RobotData& s = d.robots[i];
  RobotData::Sensor& z = s.sensor;
  const SensorOptions& o = m.robots[i].sensor;
  const long k = d.k;
  // an ideal sensor's reading depends on the present state alone: read at the log's rows, or when asked
  const bool ideal = o.noise_force == 0 && o.noise_moment == 0 && o.time_constant == 0;
  if (ideal && !now && !(m.options.log_every > 0 && k % m.options.log_every == 0)) {
    z.stale = true;
    return;
  }
  z.stale = false;
  if (z.at != k) {
    z.has_prev = z.at >= 0;
    z.prev = z.clamp;
    z.at = k;
    if (o.noise_force > 0 || o.noise_moment > 0) {
      for (int c = 0; c < 6; ++c) z.noise[c] = (c < 3 ? o.noise_force : o.noise_moment) * z.normal(z.rng);
    } else {
      z.noise.setZero();
    }
  }
  const Robot& r = m.robots[i].robot;
  const bool acting = !s.contact.wrenches.empty() || !s.external.wrenches.empty();
  if (!acting && z.noise.isZero(0) && (!z.has_prev || z.prev.isZero(0))) {
    // nothing acts and nothing is left to filter: the reading is zero without kinematics
    z.true_clamp.setZero();
    z.true_world.setZero();
    z.clamp.setZero();
    z.world.setZero();
    return;
  }
  Workspace& ws = s.ws;
  if (!framed) r.kinematics(s.state.q.data(), ws, false);
  const Eigen::Isometry3d T = r.tool_pose(ws);
  const Eigen::Vector3d p = T.translation();
  const int n = r.dof();
  const int L = r.clamp().present() ? r.clamp().fixed_link : r.tool().link;
  // minus what acts on links >= L from outside, about the TCP, world axes
  Vec6 h = Vec6::Zero();
  auto add = [&](const Eigen::Vector3d& at, const Vec6& w) {
    h.head<3>() -= w.head<3>();
    h.tail<3>() -= w.tail<3>() + (at - p).cross(w.head<3>());
  };
  for (const ExternalWrench& w : s.contact.wrenches)
    if (w.link >= L) add(ws.o[w.link] + ws.R[w.link] * w.point, w.wrench);
  for (const ExternalWrench& w : s.external.wrenches) {
    if (w.at_tool) {
      add(p, w.wrench);
      continue;
    }
    const int l = w.link < 0 ? n + 1 + w.link : w.link;
    if (l >= L) add(ws.o[l] + ws.R[l] * w.point, w.wrench);
  }
  const Eigen::Matrix3d& R = T.linear();
  z.true_world = h;
  z.true_clamp.head<3>() = R.transpose() * h.head<3>();
  z.true_clamp.tail<3>() = R.transpose() * h.tail<3>();
  const Vec6 x = z.true_clamp + z.noise;
  if (z.has_prev && o.time_constant > 0) {
    const double a = -std::expm1(-m.options.dt / o.time_constant);  // 1 - exp(-dt / tau)
    z.clamp = z.prev + a * (x - z.prev);
  } else {
    z.clamp = x;
  }
  z.world.head<3>() = R * z.clamp.head<3>();
  z.world.tail<3>() = R * z.clamp.tail<3>();
}

}  // namespace stages

}  // namespace coopsim
