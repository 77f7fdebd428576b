// Simulation::pair_readout: what a learning environment reads of two robots holding one body after each of
// its steps, for several simulations in one call (coopsim.envs: the observation and the carry's checks).
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "coopsim/simulation.hpp"
#include "coopsim/world.hpp"

namespace coopsim {

namespace {

// The quaternion [w, x, y, z] (w >= 0) of the rotation m, each part from the diagonal, its sign from the
// off-diagonal (as coopsim.envs.carry's _quaternion of Python floats: the same operations in the same order).
void put_quaternion(const Eigen::Matrix3d& m, double* out) {
  out[0] = std::sqrt(std::max(0.0, 1.0 + m(0, 0) + m(1, 1) + m(2, 2))) / 2.0;
  out[1] = std::copysign(std::sqrt(std::max(0.0, 1.0 + m(0, 0) - m(1, 1) - m(2, 2))) / 2.0, m(2, 1) - m(1, 2));
  out[2] = std::copysign(std::sqrt(std::max(0.0, 1.0 - m(0, 0) + m(1, 1) - m(2, 2))) / 2.0, m(0, 2) - m(2, 0));
  out[3] = std::copysign(std::sqrt(std::max(0.0, 1.0 - m(0, 0) - m(1, 1) + m(2, 2))) / 2.0, m(1, 0) - m(0, 1));
}

template <class V>
double* put(const V& v, double* out) {
  for (Eigen::Index k = 0; k < v.size(); ++k) *out++ = v[k];
  return out;
}

}  // namespace

Simulation::ReadoutRows Simulation::pair_readout(const std::vector<Simulation*>& sims, int a, int b,
                                                 const std::string& body) {
  if (sims.empty()) return ReadoutRows(0, 0);
  for (const Simulation* s : sims)
    if (s == nullptr) throw std::invalid_argument("sims must be simulations, got None");
  const int na = sims[0]->robot_count() > a && a >= 0 ? sims[0]->robot(a).dof() : 0;
  const int nb = sims[0]->robot_count() > b && b >= 0 ? sims[0]->robot(b).dof() : 0;
  ReadoutRows rows(static_cast<Eigen::Index>(sims.size()), pair_readout_width(na, nb));
  for (size_t k = 0; k < sims.size(); ++k) {
    Simulation& s = *sims[k];
    if (!s.data_.world) throw std::invalid_argument("sims[" + std::to_string(k) + "] has no world");
    const int id = s.data_.world->id(body);
    bool together = false;
    const Cooperation c = s.cooperation(a, b, &together);  // checks 0 <= a < b < robot_count()
    if (s.robot(a).dof() != na || s.robot(b).dof() != nb)
      throw std::invalid_argument("sims must have robots a and b of the same joints as sims[0]'s, sims[" +
                                  std::to_string(k) + "] has not");
    double* out = rows.row(static_cast<Eigen::Index>(k)).data();
    *out++ = s.time();
    *out++ = together ? 1.0 : 0.0;
    *out++ = s.holding(a) == id ? 1.0 : 0.0;
    *out++ = s.holding(b) == id ? 1.0 : 0.0;
    *out++ = static_cast<double>(s.data_.world->events().size());
    *out++ = static_cast<double>(s.data_.grasp_events.size());
    for (const int i : {a, b}) {
      const Robot& r = s.robot(i);
      const RobotData& d = s.data_.robots[i];
      Workspace ws;
      r.kinematics(d.state.q.data(), ws, false);
      const Eigen::Isometry3d T = r.tool_pose(ws);
      Mat6N J(6, r.dof());
      r.tool_jacobian(ws, J);
      out = put(d.state.q, out);
      out = put(d.state.qd, out);
      out = put(T.translation(), out);
      put_quaternion(T.linear(), out);
      out += 4;
      out = put(Vec6(J * d.state.qd), out);
      out = put(s.ft_world(i), out);
    }
    const BodyState bs = s.body_state(id);
    out = put(bs.pose.translation(), out);
    put_quaternion(bs.pose.linear(), out);
    out += 4;
    out = put(bs.velocity, out);
    out = put(bs.angular_velocity, out);
    if (together) {
      out = put(c.internal, out);
      *out++ = c.squeeze;
      out = put(c.load_share, out);
    } else {
      std::fill(out, out + 15, 0.0);
    }
  }
  return rows;
}

}  // namespace coopsim
