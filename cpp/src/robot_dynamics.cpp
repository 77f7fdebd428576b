// The serial robot's dynamics (robot.hpp): each call dispatched to the generated closed-form code when
// the robot has it, else to the numeric recursive algorithms (composite rigid bodies for the mass
// matrix, recursive Newton-Euler for the bias and inverse dynamics, the mass matrix's derivatives for
// the Coriolis matrix); external and end-stop torques, forward dynamics and its small SPD solve, energies.
#include "coopsim/robot.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "coopsim/generated.hpp"
#include "internal.hpp"

namespace coopsim {

namespace {

using detail::require;

// |r|^2 E - r r^T: the parallel-axis term per unit mass
Eigen::Matrix3d shift_inertia(const Eigen::Vector3d& r) {
  Eigen::Matrix3d P = -r * r.transpose();
  P.diagonal().array() += r.squaredNorm();
  return P;
}

}  // namespace

void Robot::mass_matrix(const double* q, Workspace& ws, MatN& M) const {
  M.resize(n_, n_);
  if (uses_generated()) {
    generated_->mass_matrix(gen_params_.data(), q, M.data());
    return;
  }
  kinematics(q, ws);
  mass_matrix_kin_(ws, M);
}

void Robot::mass_matrix_kin_(Workspace& ws, MatN& M) const {
  if (ws.M_valid) {  // computed at these kinematics already (see Workspace)
    M = ws.M;
    return;
  }
  // composite rigid bodies: links k..n-1, mass, CoM and inertia about the CoM
  for (int k = n_ - 1; k >= 0; --k) {
    const double m = links_[k].mass;
    if (k == n_ - 1) {
      ws.cm_m[k] = m;
      ws.cm_c[k] = ws.c[k];
      ws.cm_I[k] = ws.Iw[k];
    } else {
      const double mc = m + ws.cm_m[k + 1];
      // links without mass: any point will do as the (massless) composite's CoM
      const Eigen::Vector3d cc = mc > 0 ? Eigen::Vector3d((m * ws.c[k] + ws.cm_m[k + 1] * ws.cm_c[k + 1]) / mc)
                                        : ws.c[k];
      ws.cm_I[k] = ws.Iw[k] + m * shift_inertia(ws.c[k] - cc) + ws.cm_I[k + 1] +
                   ws.cm_m[k + 1] * shift_inertia(ws.cm_c[k + 1] - cc);
      ws.cm_m[k] = mc;
      ws.cm_c[k] = cc;
    }
  }
  // column k: momentum of composite body k under a unit rate of joint k,
  // projected on joints j <= k
  for (int k = 0; k < n_; ++k) {
    const Eigen::Vector3d z = ws.R[k].col(2);
    const Eigen::Vector3d r = ws.cm_c[k] - ws.o[k];
    Eigen::Vector3d h, L;
    if (links_[k].type == JointType::Revolute) {
      h = ws.cm_m[k] * z.cross(r);
      L = ws.cm_I[k] * z + r.cross(h);
      M(k, k) = z.dot(L);
    } else {
      h = ws.cm_m[k] * z;
      L = r.cross(h);
      M(k, k) = z.dot(h);
    }
    for (int j = 0; j < k; ++j) {
      const Eigen::Vector3d zj = ws.R[j].col(2);
      double v;
      if (links_[j].type == JointType::Revolute) {
        v = zj.dot(L + (ws.o[k] - ws.o[j]).cross(h));
      } else {
        v = zj.dot(h);
      }
      M(j, k) = v;
      M(k, j) = v;
    }
    M(k, k) += links_[k].armature;
  }
  ws.M = M;
  ws.M_valid = true;
}

void Robot::rnea(const double* q, const double* qd, const double* qdd, Workspace& ws, VecN& tau,
                 double gravity_scale, bool with_friction) const {
  tau.resize(n_);
  if (uses_generated() && generated_->dynamics && gravity_scale == 1.0 && with_friction) {
    MatN M(n_, n_);
    generated_->dynamics(gen_params_.data(), q, qd, M.data(), tau.data());
    if (qdd) tau.noalias() += M * Eigen::Map<const VecN>(qdd, n_);
    return;
  }
  if (uses_generated()) {
    const double* p = gen_params_.data();
    VecN tmp(n_);
    tau.setZero();
    if (qdd) {
      MatN M(n_, n_);
      generated_->mass_matrix(p, q, M.data());
      tau.noalias() = M * Eigen::Map<const VecN>(qdd, n_);
    }
    generated_->coriolis(p, q, qd, tmp.data());
    tau += tmp;
    if (gravity_scale != 0.0) {
      generated_->gravity(p, q, tmp.data());
      tau += gravity_scale * tmp;
    }
    if (with_friction) {
      friction_torques(qd, tmp);
      tau += tmp;
    }
    return;
  }
  kinematics(q, ws);
  rnea_kin_(qd, qdd, ws, tau, gravity_scale, with_friction);
}

void Robot::rnea_kin_(const double* qd, const double* qdd, Workspace& ws, VecN& tau, double gravity_scale,
                      bool with_friction) const {
  Eigen::Vector3d w = Eigen::Vector3d::Zero(), wd = Eigen::Vector3d::Zero();
  Eigen::Vector3d ap = -gravity_scale * gravity_;  // acceleration of the joint point on the previous body
  for (int k = 0; k < n_; ++k) {
    const Eigen::Vector3d z = ws.R[k].col(2);
    const double qdk = qd[k], qddk = qdd ? qdd[k] : 0.0;
    Eigen::Vector3d aJ;
    if (links_[k].type == JointType::Revolute) {
      wd += z * qddk + w.cross(z * qdk);
      w += z * qdk;
      aJ = ap;
    } else {
      aJ = ap + z * qddk + 2.0 * w.cross(z * qdk);
    }
    const Eigen::Vector3d rc = ws.c[k] - ws.o[k];
    const Eigen::Vector3d ac = aJ + wd.cross(rc) + w.cross(w.cross(rc));
    const Eigen::Vector3d rn = ws.o[k + 1] - ws.o[k];
    ap = aJ + wd.cross(rn) + w.cross(w.cross(rn));
    ws.f[k] = links_[k].mass * ac;
    ws.nm[k] = ws.Iw[k] * wd + w.cross(ws.Iw[k] * w);
  }
  Eigen::Vector3d F = Eigen::Vector3d::Zero(), N = Eigen::Vector3d::Zero();  // about o[k+1]
  for (int k = n_ - 1; k >= 0; --k) {
    const Eigen::Vector3d rn = ws.o[k + 1] - ws.o[k];
    N = ws.nm[k] + (ws.c[k] - ws.o[k]).cross(ws.f[k]) + N + rn.cross(F);  // about o[k]
    F += ws.f[k];
    const Eigen::Vector3d z = ws.R[k].col(2);
    tau[k] = links_[k].type == JointType::Revolute ? z.dot(N) : z.dot(F);
    if (qdd) tau[k] += links_[k].armature * qdd[k];
    if (with_friction) {
      const Link& L = links_[k];
      tau[k] += L.friction * qd[k] + (L.coulomb > 0 ? L.coulomb * std::tanh(qd[k] / L.coulomb_width) : 0.0);
    }
  }
}

void Robot::gravity(const double* q, Workspace& ws, VecN& g) const {
  g.resize(n_);
  if (uses_generated()) {
    generated_->gravity(gen_params_.data(), q, g.data());
    return;
  }
  VecN zero = VecN::Zero(n_);
  rnea(q, zero.data(), nullptr, ws, g, 1.0, false);
}

void Robot::coriolis_vector(const double* q, const double* qd, Workspace& ws, VecN& c) const {
  c.resize(n_);
  if (uses_generated()) {
    generated_->coriolis(gen_params_.data(), q, qd, c.data());
    return;
  }
  rnea(q, qd, nullptr, ws, c, 0.0, false);
}

void Robot::mass_matrix_derivatives(const double* q, Workspace& ws, std::vector<MatN>& dM) const {
  kinematics(q, ws);
  const int n = n_;
  dM.assign(n, MatN::Zero(n, n));
  auto isR = [&](int j) { return links_[j].type == JointType::Revolute; };
  Mat6N J(6, n), dJ(6, n);
  for (int l = 0; l < n; ++l) {
    const Eigen::Vector3d& cl = ws.c[l];
    const Eigen::Matrix3d& I = ws.Iw[l];
    const double m = links_[l].mass;
    // CoM Jacobian of link l
    J.setZero();
    for (int j = 0; j <= l; ++j) {
      const Eigen::Vector3d z = ws.R[j].col(2);
      if (isR(j)) {
        J.col(j).head<3>() = z.cross(cl - ws.o[j]);
        J.col(j).tail<3>() = z;
      } else {
        J.col(j).head<3>() = z;
      }
    }
    for (int k = 0; k <= l; ++k) {
      const Eigen::Vector3d zk = ws.R[k].col(2);
      dJ.setZero();
      for (int j = 0; j <= l; ++j) {
        const Eigen::Vector3d z = ws.R[j].col(2);
        Eigen::Vector3d dz = Eigen::Vector3d::Zero();
        if (k < j && isR(k)) dz = zk.cross(z);
        if (isR(j)) {
          // d/dq_k [z_j x (c_l - o_j)]
          Eigen::Vector3d dr;  // d(c_l - o_j)/dq_k
          if (k < j) {
            dr = isR(k) ? Eigen::Vector3d(zk.cross(cl - ws.o[j])) : Eigen::Vector3d::Zero();
          } else {
            dr = isR(k) ? Eigen::Vector3d(zk.cross(cl - ws.o[k])) : zk;
          }
          dJ.col(j).head<3>() = dz.cross(cl - ws.o[j]) + z.cross(dr);
          dJ.col(j).tail<3>() = dz;
        } else {
          dJ.col(j).head<3>() = dz;
        }
      }
      const auto Jv = J.topRows<3>();
      const auto Jw = J.bottomRows<3>();
      const auto dJv = dJ.topRows<3>();
      const auto dJw = dJ.bottomRows<3>();
      MatN A = m * (dJv.transpose() * Jv) + dJw.transpose() * (I * Jw);
      MatN& D = dM[k];
      D += A + A.transpose();
      if (isR(k)) {
        const Eigen::Matrix3d S = detail::skew(zk);
        const Eigen::Matrix3d dI = S * I - I * S;
        D += Jw.transpose() * dI * Jw;
      }
    }
  }
}

void Robot::coriolis_matrix(const double* q, const double* qd, Workspace& ws, MatN& C) const {
  C.resize(n_, n_);
  if (uses_generated()) {
    generated_->coriolis_matrix(gen_params_.data(), q, qd, C.data());
    return;
  }
  std::vector<MatN> dM;
  mass_matrix_derivatives(q, ws, dM);
  C.setZero();
  for (int k = 0; k < n_; ++k)
    for (int j = 0; j < n_; ++j) {
      double s = 0;
      for (int i = 0; i < n_; ++i) s += (dM[i](k, j) + dM[j](k, i) - dM[k](i, j)) * qd[i];
      C(k, j) = 0.5 * s;
    }
}

void Robot::external_torques(const std::vector<ExternalWrench>& wrenches, Workspace& ws, VecN& tau) const {
  tau.setZero(n_);
  Mat6N J;
  for (const ExternalWrench& w : wrenches) {
    require(w.point.allFinite() && w.wrench.allFinite(), "external wrench must be finite");
    if (w.at_tool) {
      tool_jacobian(ws, J);
    } else {
      const int l = link_index_(w.link, "external wrench link");
      jacobian(ws, l, w.point, J);
    }
    tau.noalias() += J.transpose() * w.wrench;
  }
}

void Robot::inverse_dynamics(const double* q, const double* qd, const double* qdd, const double* tau_ext,
                             Workspace& ws, VecN& tau) const {
  rnea(q, qd, qdd, ws, tau, 1.0, true);
  if (tau_ext) tau -= Eigen::Map<const VecN>(tau_ext, n_);
}

void Robot::end_stop_torques(const double* q, const double* qd, const MatN& M, VecN& tau) const {
  tau.setZero(n_);
  add_end_stop_torques_(q, qd, M, tau);
}

void Robot::add_end_stop_torques_(const double* q, const double* qd, const MatN& M, VecN& tau) const {
  const double w = end_stop_.frequency;
  if (w <= 0) return;
  for (int j = 0; j < n_; ++j) {
    const Link& L = links_[j];
    double pen = 0;
    if (q[j] > L.q_max) pen = q[j] - L.q_max;
    else if (q[j] < L.q_min) pen = q[j] - L.q_min;
    else continue;
    const double k = M(j, j) * w * w;
    const double b = 2.0 * end_stop_.damping_ratio * w * M(j, j);
    double t = -k * pen - b * qd[j];
    // a stop pushes, never pulls the joint towards the limit
    if (pen > 0 && t > 0) t = 0;
    if (pen < 0 && t < 0) t = 0;
    tau[j] += t;
  }
}

void Robot::forward_dynamics(const double* q, const double* qd, const double* tau, const double* tau_ext,
                             Workspace& ws, VecN& qdd, bool end_stops) const {
  MatN M;
  VecN b;
  if (uses_generated() && generated_->dynamics) {
    M.resize(n_, n_);
    b.resize(n_);
    generated_->dynamics(gen_params_.data(), q, qd, M.data(), b.data());
  } else if (uses_generated()) {
    mass_matrix(q, ws, M);
    rnea(q, qd, nullptr, ws, b, 1.0, true);
  } else {
    kinematics(q, ws);
    M.resize(n_, n_);
    mass_matrix_kin_(ws, M);
    b.resize(n_);
    rnea_kin_(qd, nullptr, ws, b, 1.0, true);
  }
  // rhs = tau - b (+ tau_ext) (+ the end stops' torques), element by element; with generated code
  // it is solved in place in qdd, nothing copied
  auto right_side = [&](VecN& r) {
    r.resize(n_);
    for (int j = 0; j < n_; ++j) r[j] = tau[j] - b[j];
    if (tau_ext)
      for (int j = 0; j < n_; ++j) r[j] += tau_ext[j];
    if (end_stops) add_end_stop_torques_(q, qd, M, r);
  };
  VecN rhs;
  bool ok;
  if (uses_generated() && generated_->solve) {
    right_side(qdd);  // generated LDL^T that skips M's structural zeros
    ok = generated_->solve(M.data(), qdd.data());
    if (!ok) right_side(rhs);  // M is unchanged: the right side again, for the message
  } else {
    right_side(rhs);
    ok = solve_spd(M, rhs, qdd);
  }
  if (!ok) {
    if (!M.allFinite() || !rhs.allFinite())
      throw std::domain_error("forward_dynamics: the mass matrix or the forces overflow for this state (values out "
                              "of range?)");
    std::ostringstream s;
    s.precision(17);
    s << "forward_dynamics: the mass matrix is not positive definite at q = [";
    for (int k = 0; k < n_; ++k) s << (k ? ", " : "") << q[k];
    s << "] of robot '" << name_
      << "': some joint moves no mass or inertia there (links without mass or inertia?), or values are out of "
         "range";
    throw std::domain_error(s.str());
  }
}

namespace {

// Cholesky factorisation and solve with the size known at compile time, so
// the loops unroll; a[i + j * N] is column-major.
template <int N>
bool solve_spd_fixed(double* a, const double* b, double* x) {
  for (int j = 0; j < N; ++j) {
    const double d0 = a[j + j * N];
    double d = d0;
    for (int k = 0; k < j; ++k) d -= a[j + k * N] * a[j + k * N];
    // a pivot lost to rounding is as singular as a zero one
    if (!(d > 1e-13 * d0)) return false;
    d = std::sqrt(d);
    a[j + j * N] = d;
    const double inv = 1.0 / d;
    for (int i = j + 1; i < N; ++i) {
      double s = a[i + j * N];
      for (int k = 0; k < j; ++k) s -= a[i + k * N] * a[j + k * N];
      a[i + j * N] = s * inv;
    }
  }
  for (int i = 0; i < N; ++i) {
    double s = b[i];
    for (int k = 0; k < i; ++k) s -= a[i + k * N] * x[k];
    x[i] = s / a[i + i * N];
  }
  for (int i = N - 1; i >= 0; --i) {
    double s = x[i];
    for (int k = i + 1; k < N; ++k) s -= a[k + i * N] * x[k];
    x[i] = s / a[i + i * N];
  }
  return true;
}

template <int... Ns>
bool solve_spd_dispatch(int n, double* a, const double* b, double* x, std::integer_sequence<int, Ns...>) {
  bool ok = false;
  ((n == Ns + 1 ? (ok = solve_spd_fixed<Ns + 1>(a, b, x), true) : false) || ...);
  return ok;
}

}  // namespace

bool solve_spd(MatN& A, const VecN& b, VecN& x) {
  // plain Cholesky, unrolled per size: far fewer instructions than Eigen's
  // blocked LLT on these small matrices
  const int n = static_cast<int>(A.rows());
  x.resize(n);
  return solve_spd_dispatch(n, A.data(), b.data(), x.data(), std::make_integer_sequence<int, kMaxDof>());
}

double Robot::kinetic_energy(const double* q, const double* qd, Workspace& ws) const {
  MatN M;
  mass_matrix(q, ws, M);
  const Eigen::Map<const VecN> v(qd, n_);
  return 0.5 * v.dot(M * v);
}

double Robot::potential_energy(const double* q, Workspace& ws) const {
  kinematics(q, ws);
  double V = 0;
  for (int k = 0; k < n_; ++k) V -= links_[k].mass * gravity_.dot(ws.c[k]);
  return V;
}

}  // namespace coopsim
