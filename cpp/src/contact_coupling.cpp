// The coupling of the robots with the world, the world's side of the step: the links' poses and
// twists into the world, the world's step, and its contacts back as joint torques. Bullet's solver
// gives the forces between free bodies and anything; where both sides are robots' links or
// scenery, a penalty force (critically damped, stiffness from the effective mass along the
// normal) stands in. Every force on a link, and the welds' reaction on the clamps, becomes a
// wrench whose J^T is held over the world step.
#include <algorithm>

#include "coopsim/simulation.hpp"
#include "simulation_internal.hpp"
#include "stages.hpp"

namespace coopsim {

namespace stages {

void frames(const Robot& r, RobotData& s) {
  r.kinematics(s.state.q.data(), s.ws);
  r.frame_velocities(s.ws, s.state.qd.data(), s.contact.frame_w.data(), s.contact.frame_v.data());
}

void links_to_world(const Model& m, Data& d) {
  World& w = *d.world;
  // link bodies where the robots are now, with their exact twists
  std::vector<Eigen::Isometry3d>& poses = d.box_poses;
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    const Robot& r = m.robots[i].robot;
    r.kinematics(s.state.q.data(), s.ws, false);  // the frames (what follows reads no centre of mass or inertia)
    r.frame_velocities(s.ws, s.state.qd.data(), s.contact.frame_w.data(), s.contact.frame_v.data());
    r.box_poses(s.ws, poses);
    for (size_t b = 0; b < poses.size(); ++b) {
      const int l = r.boxes()[b].link;
      w.set_link(s.contact.first_body + static_cast<int>(b), poses[b], point_velocity(s, l, poses[b].translation()),
                 s.contact.frame_w[l]);
    }
    s.contact.M_valid = false;
  }
  // free bodies as they are at t_k, for the log and body_state()
  for (size_t b = 0; b < d.free_ids.size(); ++b) d.body_now[b] = w.state(d.free_ids[b]);
}

void world_advance(const Model& m, Data& d, double h) {
  for (const auto& w : d.body_wrenches) d.world->apply_wrench(w.first, w.second.head<3>(), w.second.tail<3>());
  try {
    d.world->step(h, d.time(m));
  } catch (const WorldDivergence& e) {
    world_diverged(m, d, e, h);
  }
}

void contacts_to_robots(const Model& m, Data& d, double h) {
  contact_wrenches(m, d, h);
  d.world->record_events(d.time(m));
  if (m.options.log_contacts)
    for (const ContactPoint& c : d.world->contacts()) d.contact_log.push_back(LoggedContact{d.time(m), c});
}

Eigen::Vector3d point_velocity(const RobotData& s, int link, const Eigen::Vector3d& p) {
  return s.contact.frame_v[link] + s.contact.frame_w[link].cross(p - s.ws.o[link]);
}

namespace {

// J_v^T n (n,) for the world point p fixed on `link` of a robot (kinematics in its ws).
VecN normal_jacobian(const Robot& r, const Workspace& ws, int link, const Eigen::Vector3d& p, const Eigen::Vector3d& n) {
  Mat6N J;
  r.jacobian(ws, link, ws.R[link].transpose() * (p - ws.o[link]), J);
  return J.topRows<3>().transpose() * n;
}

// A penalty force where Bullet's solver gives none (link against scenery or another link), then
// every force on a link as a wrench at its point.
void link_contacts(const Model& m, Data& d, double h) {
  World& w = *d.world;
  std::vector<ContactPoint>& contacts = w.contacts();
  // pushing only, critically damped, stiffness from the effective mass along the normal so that
  // omega * h stays at contact_frequency_dt
  const double omega = m.options.contact_frequency_dt / h;
  for (ContactPoint& c : contacts) {
    if (c.solver || c.depth <= 0) continue;
    const BodySpec& A = w.body(c.a);
    const BodySpec& B = w.body(c.b);
    if (A.kind != BodyKind::Link && B.kind != BodyKind::Link) continue;
    double inv_mass = 0.0;
    Eigen::Vector3d va = Eigen::Vector3d::Zero(), vb = Eigen::Vector3d::Zero();
    if (A.kind == BodyKind::Link) va = point_velocity(d.robots[A.robot], A.link, c.point_a);
    if (B.kind == BodyKind::Link) vb = point_velocity(d.robots[B.robot], B.link, c.point_b);
    if (A.kind == BodyKind::Link && B.kind == BodyKind::Link && A.robot == B.robot) {
      RobotData& s = d.robots[A.robot];
      const Robot& r = m.robots[A.robot].robot;
      const VecN u = normal_jacobian(r, s.ws, A.link, c.point_a, c.normal) -
                     normal_jacobian(r, s.ws, B.link, c.point_b, c.normal);
      inv_mass = inverse_mass_along(r, s, u);
    } else {
      if (A.kind == BodyKind::Link) {
        RobotData& s = d.robots[A.robot];
        const Robot& r = m.robots[A.robot].robot;
        inv_mass += inverse_mass_along(r, s, normal_jacobian(r, s.ws, A.link, c.point_a, c.normal));
      }
      if (B.kind == BodyKind::Link) {
        RobotData& s = d.robots[B.robot];
        const Robot& r = m.robots[B.robot].robot;
        inv_mass += inverse_mass_along(r, s, normal_jacobian(r, s.ws, B.link, c.point_b, c.normal));
      }
    }
    if (!(inv_mass > 1e-12)) continue;  // neither side can move along the normal
    const double mass = 1.0 / inv_mass;
    const double closing = -(va - vb).dot(c.normal);  // > 0: approaching
    const double f = mass * omega * omega * c.depth + 2.0 * mass * omega * closing;
    c.force = std::max(f, 0.0) * c.normal;
  }
  // every force on a link, as a wrench at its point
  for (const ContactPoint& c : contacts) {
    if (c.force.squaredNorm() == 0.0) continue;
    for (int side = 0; side < 2; ++side) {
      const BodySpec& body = w.body(side == 0 ? c.a : c.b);
      if (body.kind != BodyKind::Link || body.link == 0) continue;
      RobotData& s = d.robots[body.robot];
      const Eigen::Vector3d& p = side == 0 ? c.point_a : c.point_b;
      ExternalWrench wr;
      wr.link = body.link;
      wr.point = s.ws.R[body.link].transpose() * (p - s.ws.o[body.link]);
      wr.wrench.head<3>() = side == 0 ? c.force : Eigen::Vector3d(-c.force);
      s.contact.wrenches.push_back(wr);
    }
  }
}

}  // namespace

// u^T M^-1 u for a robot at its q (M factored once per world step).
void factor_mass(const Robot& r, RobotData& s) {
  if (s.contact.M_valid) return;
  MatN M;
  r.mass_matrix(s.state.q.data(), s.ws, M);
  s.contact.M_llt.compute(M);
  if (s.contact.M_llt.info() != Eigen::Success)
    throw std::runtime_error("the mass matrix of robot '" + r.name() + "' is not positive definite at q = " +
                             detail::vec_str(s.state.q));
  s.contact.M_valid = true;
}

double inverse_mass_along(const Robot& r, RobotData& s, const VecN& u) {
  factor_mass(r, s);
  // u^T M^-1 u = |L^-1 u|^2
  return s.contact.M_llt.matrixL().solve(u).squaredNorm();
}

void contact_wrenches(const Model& m, Data& d, double h) {
  for (RobotData& s : d.robots) s.contact.wrenches.clear();
  if (m.options.contact_forces) link_contacts(m, d, h);
  // a held body pulls on its holder's clamp link: the weld's wrench, opposite, at the weld's point
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    if (s.grasp.held < 0) continue;
    ExternalWrench wr;
    wr.link = m.robots[i].robot.clamp().fixed_link;
    wr.point = s.grasp.anchor_link;
    wr.wrench = -s.grasp.weld;
    s.contact.wrenches.push_back(wr);
  }
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    const Robot& r = m.robots[i].robot;
    s.contact.any = !s.contact.wrenches.empty();
    if (s.contact.any) r.external_torques(s.contact.wrenches, s.ws, s.contact.tau);
    else s.contact.tau.setZero();
    if (s.grasp.held >= 0) {
      // the moving jaw meets the held body as a stop at its width (as the joints' end stops)
      const int j = r.clamp().moving_joint - 1;
      const double pen = s.grasp.width - s.state.q[j];
      if (pen > 0) {
        MatN M;
        r.mass_matrix(s.state.q.data(), s.ws, M);
        const double w = r.end_stop().frequency, z = r.end_stop().damping_ratio;
        s.contact.tau[j] += std::max(0.0, M(j, j) * (w * w * pen - 2.0 * z * w * s.state.qd[j]));
        s.contact.any = true;
      }
    }
  }
}

}  // namespace stages

void Simulation::set_body_wrench(int id, const Vec6& wrench) {
  const Entry driving = enter_();  // one driver at a time
  if (!data_.world) throw std::invalid_argument("the simulation has no world");
  const BodySpec& b = data_.world->body(id);
  if (b.kind != BodyKind::Free)
    throw std::invalid_argument("body '" + b.name + "' is not a free body: only free bodies take a wrench");
  if (!wrench.allFinite()) throw std::invalid_argument("wrench on body '" + b.name + "' must be finite");
  auto& all = data_.body_wrenches;
  for (auto it = all.begin(); it != all.end(); ++it)
    if (it->first == id) {
      all.erase(it);
      break;
    }
  if (!wrench.isZero(0)) all.emplace_back(id, wrench);
}

Vec6 Simulation::body_wrench(int id) const {
  for (const auto& w : data_.body_wrenches)
    if (w.first == id) return w.second;
  return Vec6::Zero();
}

}  // namespace coopsim
