// The coupling of the robots with the world, the world's side of the step: the links' poses and
// twists into the world, the world's step, and its contacts back as joint torques. Bullet's solver
// gives the forces between free bodies and anything; where both sides are robots' links or
// scenery, a penalty force (critically damped, stiffness from the effective mass along the
// normal) stands in. Every force on a link, and the welds' reaction on the clamps, becomes a
// wrench whose J^T is held over the world step.
#include <algorithm>

#include "coopsim/simulation.hpp"
#include "simulation_internal.hpp"

namespace coopsim {

void Simulation::frames_(Slot& s) {
  s.robot.kinematics(s.state.q.data(), s.ws);
  s.robot.frame_velocities(s.ws, s.state.qd.data(), s.contact.frame_w.data(), s.contact.frame_v.data());
}

void Simulation::links_to_world_() {
  World& w = *world_;
  // link bodies where the robots are now, with their exact twists
  std::vector<Eigen::Isometry3d>& poses = box_poses_;
  for (Slot& s : slots_) {
    const Robot& r = s.robot;
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
  for (size_t b = 0; b < free_ids_.size(); ++b) body_now_[b] = w.state(free_ids_[b]);
}

void Simulation::set_body_wrench(int id, const Vec6& wrench) {
  const Entry driving = enter_();  // one driver at a time
  if (!world_) throw std::invalid_argument("the simulation has no world");
  const BodySpec& b = world_->body(id);
  if (b.kind != BodyKind::Free)
    throw std::invalid_argument("body '" + b.name + "' is not a free body: only free bodies take a wrench");
  if (!wrench.allFinite()) throw std::invalid_argument("wrench on body '" + b.name + "' must be finite");
  for (auto it = body_wrenches_.begin(); it != body_wrenches_.end(); ++it)
    if (it->first == id) {
      body_wrenches_.erase(it);
      break;
    }
  if (!wrench.isZero(0)) body_wrenches_.emplace_back(id, wrench);
}

Vec6 Simulation::body_wrench(int id) const {
  for (const auto& w : body_wrenches_)
    if (w.first == id) return w.second;
  return Vec6::Zero();
}

void Simulation::world_advance_(double h) {
  for (const auto& w : body_wrenches_) world_->apply_wrench(w.first, w.second.head<3>(), w.second.tail<3>());
  try {
    world_->step(h, time());
  } catch (const WorldDivergence& e) {
    world_diverged_(e, h);
  }
}

void Simulation::contacts_to_robots_(double h) {
  contact_wrenches_(h);
  world_->record_events(time());
  if (opt_.log_contacts)
    for (const ContactPoint& c : world_->contacts()) contact_log_.push_back(LoggedContact{time(), c});
}

Eigen::Vector3d Simulation::point_velocity(const Slot& s, int link, const Eigen::Vector3d& p) {
  return s.contact.frame_v[link] + s.contact.frame_w[link].cross(p - s.ws.o[link]);
}

// J_v^T n (n,) for the world point p fixed on `link` of a slot's robot (kinematics in its ws).
static VecN normal_jacobian(const Robot& r, const Workspace& ws, int link, const Eigen::Vector3d& p,
                            const Eigen::Vector3d& n) {
  Mat6N J;
  r.jacobian(ws, link, ws.R[link].transpose() * (p - ws.o[link]), J);
  return J.topRows<3>().transpose() * n;
}

// u^T M^-1 u for the slot's robot at its q (M factored once per world step).
void Simulation::factor_mass_(Slot& s) {
  if (s.contact.M_valid) return;
  MatN M;
  s.robot.mass_matrix(s.state.q.data(), s.ws, M);
  s.contact.M_llt.compute(M);
  if (s.contact.M_llt.info() != Eigen::Success)
    throw std::runtime_error("the mass matrix of robot '" + s.robot.name() + "' is not positive definite at q = " +
                             detail::vec_str(s.state.q));
  s.contact.M_valid = true;
}

double Simulation::inverse_mass_along(Slot& s, const VecN& u) {
  factor_mass_(s);
  // u^T M^-1 u = |L^-1 u|^2
  return s.contact.M_llt.matrixL().solve(u).squaredNorm();
}

void Simulation::contact_wrenches_(double h) {
  for (Slot& s : slots_) s.contact.wrenches.clear();
  if (opt_.contact_forces) link_contacts_(h);
  // a held body pulls on its holder's clamp link: the weld's wrench, opposite, at the weld's point
  for (Slot& s : slots_) {
    if (s.grasp.held < 0) continue;
    ExternalWrench wr;
    wr.link = s.robot.clamp().fixed_link;
    wr.point = s.grasp.anchor_link;
    wr.wrench = -s.grasp.weld;
    s.contact.wrenches.push_back(wr);
  }
  for (Slot& s : slots_) {
    s.contact.any = !s.contact.wrenches.empty();
    if (s.contact.any) s.robot.external_torques(s.contact.wrenches, s.ws, s.contact.tau);
    else s.contact.tau.setZero();
    if (s.grasp.held >= 0) {
      // the moving jaw meets the held body as a stop at its width (as the joints' end stops)
      const int j = s.robot.clamp().moving_joint - 1;
      const double pen = s.grasp.width - s.state.q[j];
      if (pen > 0) {
        MatN M;
        s.robot.mass_matrix(s.state.q.data(), s.ws, M);
        const double w = s.robot.end_stop().frequency, z = s.robot.end_stop().damping_ratio;
        s.contact.tau[j] += std::max(0.0, M(j, j) * (w * w * pen - 2.0 * z * w * s.state.qd[j]));
        s.contact.any = true;
      }
    }
  }
}

void Simulation::link_contacts_(double h) {
  World& w = *world_;
  std::vector<ContactPoint>& contacts = w.contacts();
  // a penalty force where Bullet's solver gives none (link against scenery or
  // another link): pushing only, critically damped, stiffness from the
  // effective mass along the normal so that omega * h stays at contact_frequency_dt
  const double omega = opt_.contact_frequency_dt / h;
  for (ContactPoint& c : contacts) {
    if (c.solver || c.depth <= 0) continue;
    const BodySpec& A = w.body(c.a);
    const BodySpec& B = w.body(c.b);
    if (A.kind != BodyKind::Link && B.kind != BodyKind::Link) continue;
    double inv_mass = 0.0;
    Eigen::Vector3d va = Eigen::Vector3d::Zero(), vb = Eigen::Vector3d::Zero();
    if (A.kind == BodyKind::Link) va = point_velocity(slots_[A.robot], A.link, c.point_a);
    if (B.kind == BodyKind::Link) vb = point_velocity(slots_[B.robot], B.link, c.point_b);
    if (A.kind == BodyKind::Link && B.kind == BodyKind::Link && A.robot == B.robot) {
      Slot& s = slots_[A.robot];
      const VecN u = normal_jacobian(s.robot, s.ws, A.link, c.point_a, c.normal) -
                     normal_jacobian(s.robot, s.ws, B.link, c.point_b, c.normal);
      inv_mass = inverse_mass_along(s, u);
    } else {
      if (A.kind == BodyKind::Link) {
        Slot& s = slots_[A.robot];
        inv_mass += inverse_mass_along(s, normal_jacobian(s.robot, s.ws, A.link, c.point_a, c.normal));
      }
      if (B.kind == BodyKind::Link) {
        Slot& s = slots_[B.robot];
        inv_mass += inverse_mass_along(s, normal_jacobian(s.robot, s.ws, B.link, c.point_b, c.normal));
      }
    }
    if (!(inv_mass > 1e-12)) continue;  // neither side can move along the normal
    const double m = 1.0 / inv_mass;
    const double closing = -(va - vb).dot(c.normal);  // > 0: approaching
    const double f = m * omega * omega * c.depth + 2.0 * m * omega * closing;
    c.force = std::max(f, 0.0) * c.normal;
  }
  // every force on a link, as a wrench at its point
  for (const ContactPoint& c : contacts) {
    if (c.force.squaredNorm() == 0.0) continue;
    for (int side = 0; side < 2; ++side) {
      const BodySpec& body = w.body(side == 0 ? c.a : c.b);
      if (body.kind != BodyKind::Link || body.link == 0) continue;
      Slot& s = slots_[body.robot];
      const Eigen::Vector3d& p = side == 0 ? c.point_a : c.point_b;
      ExternalWrench wr;
      wr.link = body.link;
      wr.point = s.ws.R[body.link].transpose() * (p - s.ws.o[body.link]);
      wr.wrench.head<3>() = side == 0 ? c.force : Eigen::Vector3d(-c.force);
      s.contact.wrenches.push_back(wr);
    }
  }
}

}  // namespace coopsim
