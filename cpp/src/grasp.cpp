// The clamp grasp (grasp.hpp): its options by name and their check, and the grasp stage of a
// simulation's step: the clamp rule (grasping, letting go) and the welds' wrenches, between the
// links' poses entering the world and the world's step.
#include <algorithm>
#include <cmath>

#include "coopsim/grasp.hpp"
#include "coopsim/simulation.hpp"
#include "internal.hpp"
#include "simulation_internal.hpp"
#include "stages.hpp"

namespace coopsim {

const std::array<GraspOptionField, kGraspOptionFields>& grasp_option_fields() {
  static const std::array<GraspOptionField, kGraspOptionFields> fields = {{
      {"hold_time", &GraspOptions::hold_time, "s"},
      {"gap", &GraspOptions::gap, "m"},
      {"penetration", &GraspOptions::penetration, "m"},
      {"angle", &GraspOptions::angle, "rad"},
      {"speed", &GraspOptions::speed, "m/s"},
      {"angular_speed", &GraspOptions::angular_speed, "rad/s"},
      {"open_margin", &GraspOptions::open_margin, "m"},
      {"slip", &GraspOptions::slip, "m"},
      {"weld_omega_dt", &GraspOptions::weld_omega_dt, ""},
      {"release_time", &GraspOptions::release_time, "s"},
  }};
  return fields;
}

double& grasp_option(GraspOptions& g, const std::string& name) {
  for (const GraspOptionField& f : grasp_option_fields())
    if (name == f.name) return g.*f.field;
  throw std::invalid_argument("grasp_options: unknown option '" + name + "'");
}

void check_grasp_options(const GraspOptions& g) {
  for (const GraspOptionField& f : grasp_option_fields()) {
    const double v = g.*f.field;
    if (!(v >= 0))
      throw std::invalid_argument(std::string("grasp_options: ") + f.name + " must be >= 0" +
                                  (*f.unit ? std::string(" ") + f.unit : std::string()) + ", got " + detail::num(v));
  }
}

namespace stages {

namespace {

// The grasp rule's first condition: the jaw commanded closing or closed.
bool jaw_closing(double q_ref, double q, double qd_ref) { return q_ref <= q + 1e-9 || qd_ref < 0; }

void grasp_rule(const Model& m, Data& d, double h);
void welds(const Model& m, Data& d, double h);

}  // namespace

// The grasp stage: the rule, then the welds' wrenches on the held bodies over the world step h.
void grasp(const Model& m, Data& d, double h) {
  detail::Stopwatch watch(d.profiling, d.profile.grasp);
  if (!m.options.grasp.enabled) return;
  grasp_rule(m, d, h);
  welds(m, d, h);
}

GraspCheck grasp_check(const Model& m, const Data& d, int i, const BodyState& st, int id) {
  const GraspOptions& g = m.options.grasp;
  const RobotData& s = d.robots[i];
  const Robot& r = m.robots[i].robot;
  const Clamp& c = r.clamp();
  const int j = c.moving_joint - 1, l = c.fixed_link;
  const double opening = s.state.q[j];
  GraspCheck out;
  // the jaw commanded closing or closed
  out.closing = jaw_closing(s.control.q_ref[j], opening, s.control.qd_ref[j]);
  const BodySpec& b = d.world->body(id);
  const Eigen::Isometry3d link = r.frame(s.ws, l);
  const Eigen::Isometry3d F = link * c.fixed_face;  // x along the jaw, z the jaw axis, origin the pad centre
  const Eigen::Matrix3d A = F.linear().transpose() * st.pose.linear();  // the body's axes in F
  const Eigen::Vector3d p = F.inverse() * st.pose.translation();
  const Eigen::Vector3d& he = b.half_extents;
  // a face of the body normal to the jaw axis
  int k = 0;
  for (int i = 1; i < 3; ++i)
    if (std::abs(A(2, i)) > std::abs(A(2, k))) k = i;
  out.angle = std::acos(std::min(1.0, std::abs(A(2, k))));
  out.aligned = out.angle <= g.angle;
  out.width = 2.0 * he[k];
  // both jaws touch it
  const double ez = (A.row(2).cwiseAbs().transpose().array() * he.array()).sum();
  out.gap_fixed = p.z() - ez;
  out.gap_moving = opening - (p.z() + ez);
  out.touching = out.gap_fixed <= g.gap && out.gap_fixed >= -g.penetration && out.gap_moving <= g.gap &&
                 out.gap_moving >= -g.penetration;
  // between the pads: its centre within them along the jaw (x, towards the tips; a body may stand out
  // beyond the tips, as a bar on the floor gripped above it does), not into the palm, and across their
  // centre line
  const double ex = (A.row(0).cwiseAbs().transpose().array() * he.array()).sum();
  const double ey = (A.row(1).cwiseAbs().transpose().array() * he.array()).sum();
  out.in_pads = std::abs(p.x()) <= c.jaw_length / 2 + 1e-9 && p.x() - ex >= -c.jaw_length / 2 - 1e-9 &&
                std::abs(p.y()) <= ey;
  // moving with the clamp
  out.speed = (st.velocity - point_velocity(s, l, st.pose.translation())).norm();
  out.angular_speed = (st.angular_velocity - s.contact.frame_w[l]).norm();
  out.slow = out.speed <= g.speed && out.angular_speed <= g.angular_speed;
  return out;
}

namespace {

void grasp_rule(const Model& m, Data& d, double h) {
  World& w = *d.world;
  const GraspOptions& g = m.options.grasp;
  bool changed = false;
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    const Robot& r = m.robots[i].robot;
    RobotData::Grasp& hold = s.grasp;
    const Clamp& c = r.clamp();
    if (!c.present()) continue;
    const int l = c.fixed_link;
    if (hold.held >= 0) {
      const Eigen::Isometry3d link = r.frame(s.ws, l);
      const Eigen::Vector3d target = link * hold.anchor_link;
      BodyState st = w.state(hold.held);
      if (hold.releasing) {
        // letting go by opening: the weld fades out, then the body is free (it moves on its own already)
        hold.release_progress += g.release_time > 0 ? h / g.release_time : 1.0;
        hold.release_progress = std::min(1.0, hold.release_progress);
        const double p = hold.release_progress;
        hold.fade = 1.0 - p * p * (3.0 - 2.0 * p);  // smooth at both ends: the load moves over without a jump
        if (p >= 1.0 - 1e-12) {
          release(m, d, static_cast<int>(i), "opened", false);
          changed = true;
        }
      } else if (s.control.qd_ref[c.moving_joint - 1] >= 0.0 &&
                 s.control.q_ref[c.moving_joint - 1] > hold.width + g.open_margin) {
        // opening: the jaw's reference above the body's width and not closing (a grasp made while the
        // reference still closes towards the body is kept)
        hold.releasing = true;
        hold.fade = 1.0;
        hold.release_progress = 0.0;
      } else if ((target - st.pose * hold.anchor_body).norm() > g.slip) {
        release(m, d, static_cast<int>(i), "slipped");
        changed = true;
      }
      continue;
    }
    int found = -1;
    double width = 0.0;
    const int j = c.moving_joint - 1;
    if (!jaw_closing(s.control.q_ref[j], s.state.q[j], s.control.qd_ref[j])) {  // nothing to check while the jaw opens
      hold.candidate = -1;
      continue;
    }
    for (size_t b = 0; b < d.free_ids.size(); ++b) {
      const GraspCheck c = grasp_check(m, d, static_cast<int>(i), d.body_now[b], d.free_ids[b]);
      if (c.ok()) {
        found = d.free_ids[b];
        width = c.width;
        break;
      }
    }
    if (found < 0) {
      hold.candidate = -1;
      continue;
    }
    if (hold.candidate != found) {
      hold.candidate = found;
      hold.candidate_since = d.k;
    }
    if ((d.k - hold.candidate_since) * m.options.dt < g.hold_time - 1e-12) continue;
    // attach where the body is now: no snapping
    const Eigen::Isometry3d link = r.frame(s.ws, l);
    hold.held = found;
    hold.width = width;
    const Eigen::Isometry3d body = w.state(found).pose;
    hold.weld_X = link.inverse() * body;
    // anchored midway between the pads' centres, where the clamp holds it
    const Eigen::Isometry3d face = link * c.fixed_face;
    const Eigen::Vector3d anchor = face * Eigen::Vector3d(0, 0, 0.5 * s.state.q[c.moving_joint - 1]);
    hold.anchor_link = link.inverse() * anchor;
    hold.anchor_body = body.inverse() * anchor;
    hold.candidate = -1;
    d.grasp_events.push_back(GraspEvent{d.time(m), static_cast<int>(i), found, true, "grasp"});
    pairs_attach(m, d, static_cast<int>(i));
    changed = true;
  }
  if (changed) ignore_held(m, d);
}

// Y^T Y (6 x 6) for Y (n x 6): with n = 6 (the SCARAs) each entry is the dot product of two columns summed as
// Eigen's product sums it (in pairs of rows, even and odd: ((y0 + y2) + y4) + ((y1 + y3) + y5)), to the bit,
// and each pair of symmetric entries once, without the product's per-entry set-up (about 2,000 instructions
// for the 36 entries); other sizes by Eigen's product
Eigen::Matrix<double, 6, 6> gram(const Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxDof, 6>& Y) {
  if (Y.rows() != 6) return Y.transpose() * Y;
  Eigen::Matrix<double, 6, 6> A;
  for (int a = 0; a < 6; ++a) {
    const double* u = Y.col(a).data();
    for (int c = a; c < 6; ++c) {
      const double* v = Y.col(c).data();
      const double even = (u[0] * v[0] + u[2] * v[2]) + u[4] * v[4];
      const double odd = (u[1] * v[1] + u[3] * v[3]) + u[5] * v[5];
      A(a, c) = A(c, a) = even + odd;
    }
  }
  return A;
}

void welds(const Model& model, Data& d, double h) {
  World& w = *d.world;
  const double omega = model.options.grasp.weld_omega_dt / h;
  for (size_t ri = 0; ri < d.robots.size(); ++ri) {
    RobotData& s = d.robots[ri];
    const Robot& rb = model.robots[ri].robot;
    RobotData::Grasp& hold = s.grasp;
    if (hold.held < 0) continue;
    const int l = rb.clamp().fixed_link;
    // the damping is shared among the welds on the body, a fading one counting as much as it holds
    double holders = 0.0;
    for (const RobotData& o : d.robots)
      if (o.grasp.held == hold.held) holders += o.grasp.fade;
    const BodySpec& b = w.body(hold.held);
    const BodyState st = w.state(hold.held);
    const Eigen::Isometry3d link = rb.frame(s.ws, l);
    const Eigen::Isometry3d target = link * hold.weld_X;
    const Eigen::Vector3d p_target = link * hold.anchor_link, p_body = st.pose * hold.anchor_body;
    const Eigen::Vector3d r = p_body - st.pose.translation();  // from the body's centre to the weld's point
    // the reduced mass and inertia matrices between body and robot at the weld's point (operational
    // space): every mode of the weld then rings at omega, critically damped
    Mat6N J;
    rb.jacobian(s.ws, l, hold.anchor_link, J);
    factor_mass(rb, s);  // once this world step
    // J M^-1 J^T = Y^T Y with Y = L^-1 J^T (one triangular solve for the six columns)
    Eigen::Matrix<double, Eigen::Dynamic, 6, 0, kMaxDof, 6> Y = J.transpose();
    s.contact.M_llt.matrixL().solveInPlace(Y);
    const Eigen::Matrix<double, 6, 6> A_robot = gram(Y);
    const Eigen::Matrix3d I_inv = w.inertia(hold.held).inverse();
    Eigen::Matrix3d rx;
    rx << 0, -r.z(), r.y(), r.z(), 0, -r.x(), -r.y(), r.x(), 0;
    const Eigen::Matrix3d A_lin =
        Eigen::Matrix3d::Identity() / b.mass - rx * I_inv * rx + A_robot.topLeftCorner<3, 3>();
    const Eigen::Matrix3d A_rot = I_inv + A_robot.bottomRightCorner<3, 3>();
    const Eigen::Matrix3d m = A_lin.inverse(), i = A_rot.inverse();
    const Eigen::Vector3d e_p = p_target - p_body;
    const Eigen::AngleAxisd e_r(target.linear() * st.pose.linear().transpose());
    const Eigen::Vector3d e_v = point_velocity(s, l, p_target) - (st.velocity + st.angular_velocity.cross(r));
    const Eigen::Vector3d e_w = s.contact.frame_w[l] - st.angular_velocity;
    hold.weld.head<3>() = hold.fade * (m * (omega * omega * e_p + 2.0 * omega / holders * e_v));
    hold.weld.tail<3>() =
        hold.fade * (i * (omega * omega * e_r.angle() * e_r.axis() + 2.0 * omega / holders * e_w));
    if (!model.options.grasp.weld_moment) hold.weld.tail<3>().setZero();
    // the force acts at the weld's point: about the body's centre it also turns it
    const Eigen::Vector3d force = hold.weld.head<3>();
    w.apply_wrench(hold.held, force, hold.weld.tail<3>() + r.cross(force));
  }
}

}  // namespace

void ignore_held(const Model& m, Data& d) {
  // a held body does not collide with its holder's clamp
  std::vector<std::pair<int, int>> pairs;
  for (size_t i = 0; i < d.robots.size(); ++i) {
    const RobotData& s = d.robots[i];
    const Robot& r = m.robots[i].robot;
    if (s.grasp.held < 0) continue;
    const std::vector<LinkBox>& boxes = r.boxes();
    for (size_t b = 0; b < boxes.size(); ++b)
      if (boxes[b].link >= r.clamp().fixed_link) pairs.emplace_back(s.grasp.held, s.contact.first_body + static_cast<int>(b));
  }
  d.world->set_ignored(std::move(pairs));
}

void release(const Model& m, Data& d, int i, const std::string& why, bool set_twist) {
  RobotData& s = d.robots[i];
  if (s.grasp.held < 0) return;
  const Robot& r = m.robots[i].robot;
  const int l = r.clamp().fixed_link;
  frames(r, s);
  const BodyState st = d.world->state(s.grasp.held);
  // the body leaves with the clamp's rigid twist at its centre of mass
  if (set_twist) d.world->set_velocity(s.grasp.held, point_velocity(s, l, st.pose.translation()), s.contact.frame_w[l]);
  s.grasp.releasing = false;
  s.grasp.fade = 1.0;
  d.grasp_events.push_back(GraspEvent{d.time(m), i, s.grasp.held, false, why});
  s.grasp.held = -1;
  s.grasp.weld.setZero();
  pairs_attach(m, d, i);
}

}  // namespace stages

GraspCheck Simulation::grasp_check(int i, int body) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  const Robot& r = robot(i);
  if (!data_.world) throw std::invalid_argument("the simulation has no world");
  if (!r.clamp().present()) throw std::invalid_argument("robot '" + r.name() + "' has no clamp");
  if (data_.world->body(body).kind != BodyKind::Free) throw std::invalid_argument("only free bodies can be grasped");
  if (s.control.updated_at != data_.k) {
    if (!data_.started) stages::start(*model_, data_);
    stages::run(*model_, data_);
  }
  stages::frames(r, s);
  return stages::grasp_check(*model_, data_, i, data_.world->state(body), body);
}

void Simulation::release(int i) {
  const Entry driving = enter_();  // one driver at a time
  RobotData& s = slot_(i);
  if (s.grasp.held < 0) return;
  const SimulationModel& m = *model_;
  SimulationData& d = data_;
  stages::release(m, d, i, "released");
  stages::ignore_held(m, d);
  // its body's state now is the released one; the robots feel the weld no more from the next step
  for (size_t k = 0; k < d.free_ids.size(); ++k) d.body_now[k] = d.world->state(d.free_ids[k]);
  for (size_t k = 0; k < d.robots.size(); ++k) {
    stages::frames(m.robots[k].robot, d.robots[k]);
    d.robots[k].contact.M_valid = false;
  }
  stages::contact_wrenches(m, d, m.options.dt * m.options.world_every);
  for (size_t k = 0; k < d.robots.size(); ++k) {
    RobotData& o = d.robots[k];
    stages::external(m.robots[k], o);
    o.state.k1_valid = false;
    o.external.held = o.external.applied || o.contact.any;
    if (o.sensor.at == d.k) stages::sense_robot(m, d, static_cast<int>(k));
  }
  if (d.logged_at == d.k) d.logged_at = -1;
}

}  // namespace coopsim
