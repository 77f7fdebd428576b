// The derivatives of the serial robot's dynamics (robot.hpp): the recursive Newton-Euler algorithm
// differentiated analytically (Carpentier & Mansard, RSS 2018, the algorithm of Pinocchio's
// computeRNEADerivatives) in the world frame, for the chain of the robot's DH frames; the forward
// dynamics' derivatives from them by dqdd/dx = -M^-1 dtau/dx at qdd = FD(q, qd, tau); a batch on threads.
//
// Spatial vectors are in world axes about the world origin: a motion [w; v] (angular velocity, velocity
// of the body point at the origin), a force [n; f] (moment about the origin, force). Joint k's axis is
// S_k = [z_k; o_k x z_k] (revolute) or [0; z_k] (prismatic). With v_k, a_k the velocity and (spatial)
// acceleration of link k (a_{-1} = [0; -g]: gravity as a base acceleration), I_k its spatial inertia,
// f_k = I_k a_k + v_k x* I_k v_k, and F_k, H_k, Ic_k, Bc_k the sums over links i >= k of f_i, I_i v_i,
// I_i and B_i = (v_i x*) I_i - I_i (v_i x):
//   dS_k/dt = v_{k-1} x S_k,  Psi_k = a_{k-1} x S_k + v_{k-1} x dS_k/dt,
//   moving joint k moves links i >= k rigidly, with the extra dv_i = dS_k/dt and da_i = Psi_k + dS_k/dt x v_i,
// so that, for j <= k (upper triangle and diagonal),
//   dtau_j/dq_k  = S_j . (S_k x* F_k + Ic_k Psi_k + dS_k/dt x* H_k + Bc_k dS_k/dt)
//   dtau_j/dqd_k = S_j . (2 Ic_k dS_k/dt + Bc_k S_k + S_k x* H_k)
// and for k < j, with alpha_j = Ic_j S_j and beta_j = Bc_j^T S_j - S_j x* H_j,
//   dtau_j/dq_k  = Psi_k . alpha_j + dS_k/dt . beta_j,   dtau_j/dqd_k = 2 dS_k/dt . alpha_j + S_k . beta_j,
// and M_jk = S_min(j,k) . alpha_max(j,k) (plus the armature on the diagonal). O(n^2) in all.
#include "coopsim/robot.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <string>
#include <thread>

#include "internal.hpp"

namespace coopsim {

namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;
using detail::require;

// a x b of two motions
inline Vec6 cross_m(const Vec6& a, const Vec6& b) {
  Vec6 r;
  r.head<3>() = a.head<3>().cross(b.head<3>());
  r.tail<3>() = a.head<3>().cross(b.tail<3>()) + a.tail<3>().cross(b.head<3>());
  return r;
}

// a x* f of a motion and a force
inline Vec6 cross_f(const Vec6& a, const Vec6& f) {
  Vec6 r;
  r.head<3>() = a.head<3>().cross(f.head<3>()) + a.tail<3>().cross(f.tail<3>());
  r.tail<3>() = a.head<3>().cross(f.tail<3>());
  return r;
}

// (v x*) I - I (v x) for a symmetric I: B x = I (x x v) + v x* (I x)
inline Mat6 inertia_variation(const Vec6& v, const Mat6& I) {
  const Eigen::Matrix3d W = detail::skew(v.head<3>()), U = detail::skew(v.tail<3>());
  Mat6 X;  // the motion cross product v x
  X.topLeftCorner<3, 3>() = W;
  X.topRightCorner<3, 3>().setZero();
  X.bottomLeftCorner<3, 3>() = U;
  X.bottomRightCorner<3, 3>() = W;
  const Mat6 IX = I * X;
  return -IX.transpose() - IX;  // (v x*) = -(v x)^T, so (v x*) I = -(I (v x))^T
}

}  // namespace

void Robot::rnea_derivatives_kin_(const double* qd, const double* qdd, const Workspace& ws, MatN& dtau_dq,
                                  MatN& dtau_dqd, MatN& M) const {
  const int n = n_;
  std::array<Vec6, kMaxDof> S, Sd, Psi, alpha, beta, u, w;
  std::array<Mat6, kMaxDof> I, B;
  std::array<Vec6, kMaxDof> f, h;
  Vec6 v = Vec6::Zero(), a = Vec6::Zero();
  a.tail<3>() = -gravity_;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d z = ws.R[k].col(2);
    if (links_[k].type == JointType::Revolute) {
      S[k] << z, ws.o[k].cross(z);
    } else {
      S[k] << Eigen::Vector3d::Zero(), z;
    }
    Sd[k] = cross_m(v, S[k]);
    Psi[k] = cross_m(a, S[k]) + cross_m(v, Sd[k]);
    v += S[k] * qd[k];
    a += Sd[k] * qd[k];
    if (qdd) a += S[k] * qdd[k];
    // the link's spatial inertia about the world origin
    const double m = links_[k].mass;
    const Eigen::Matrix3d C = detail::skew(ws.c[k]);
    Mat6& Ik = I[k];
    Ik.topLeftCorner<3, 3>() = ws.Iw[k] - m * C * C;
    Ik.topRightCorner<3, 3>() = m * C;
    Ik.bottomLeftCorner<3, 3>() = -m * C;
    Ik.bottomRightCorner<3, 3>() = m * Eigen::Matrix3d::Identity();
    h[k] = Ik * v;
    f[k] = Ik * a + cross_f(v, h[k]);
    B[k] = inertia_variation(v, Ik);
  }
  // composites, from the tip: I[k], B[k], f[k], h[k] become the sums over links i >= k
  for (int k = n - 1; k >= 0; --k) {
    if (k < n - 1) {
      I[k] += I[k + 1];
      B[k] += B[k + 1];
      f[k] += f[k + 1];
      h[k] += h[k + 1];
    }
    alpha[k] = I[k] * S[k];
    beta[k] = B[k].transpose() * S[k] - cross_f(S[k], h[k]);
    u[k] = cross_f(S[k], f[k]) + I[k] * Psi[k] + cross_f(Sd[k], h[k]) + B[k] * Sd[k];
    w[k] = 2.0 * (I[k] * Sd[k]) + B[k] * S[k] + cross_f(S[k], h[k]);
  }
  dtau_dq.resize(n, n);
  dtau_dqd.resize(n, n);
  M.resize(n, n);
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j <= k; ++j) {
      dtau_dq(j, k) = S[j].dot(u[k]);
      dtau_dqd(j, k) = S[j].dot(w[k]);
      M(j, k) = S[j].dot(alpha[k]);
    }
    for (int j = k + 1; j < n; ++j) {
      dtau_dq(j, k) = Psi[k].dot(alpha[j]) + Sd[k].dot(beta[j]);
      dtau_dqd(j, k) = 2.0 * Sd[k].dot(alpha[j]) + S[k].dot(beta[j]);
      M(j, k) = S[k].dot(alpha[j]);
    }
  }
  for (int k = 0; k < n; ++k) {
    const Link& L = links_[k];
    M(k, k) += L.armature;
    double d = L.friction;
    if (L.coulomb > 0) {
      const double t = std::tanh(qd[k] / L.coulomb_width);
      d += L.coulomb / L.coulomb_width * (1.0 - t * t);
    }
    dtau_dqd(k, k) += d;
  }
}

void Robot::external_torque_derivatives_(const std::vector<ExternalWrench>& wrenches, const Workspace& ws,
                                         MatN& d) const {
  // each wrench as loads (link, world point, force, moment): J^T w is the sum of S_j . [m + p x f; f]
  // over the joints j before the link; the point moves with its link, the force and moment stay fixed
  // in the world, so d/dq_k = S_j . [dp/dq_k x f; 0] (k before the link) + (S_k x S_j) . F (k < j).
  auto add = [&](int l, const Eigen::Vector3d& p, const Eigen::Vector3d& force, const Eigen::Vector3d& moment) {
    Vec6 F;
    F << moment + p.cross(force), force;
    std::array<Vec6, kMaxDof> S;
    for (int k = 0; k < l; ++k) {
      const Eigen::Vector3d z = ws.R[k].col(2);
      if (links_[k].type == JointType::Revolute) S[k] << z, ws.o[k].cross(z);
      else S[k] << Eigen::Vector3d::Zero(), z;
    }
    for (int k = 0; k < l; ++k) {
      const Eigen::Vector3d dp = S[k].head<3>().cross(p) + S[k].tail<3>();
      const Vec6 SkF = cross_f(S[k], F);
      const Eigen::Vector3d dn = dp.cross(force);
      for (int j = 0; j < l; ++j) {
        double x = S[j].head<3>().dot(dn);
        if (k < j) x -= S[j].dot(SkF);
        d(j, k) += x;
      }
    }
  };
  for (const ExternalWrench& e : wrenches) {
    require(e.point.allFinite() && e.wrench.allFinite(), "external wrench must be finite");
    const Eigen::Vector3d force = e.wrench.head<3>(), moment = e.wrench.tail<3>();
    if (e.at_tool) {
      // the tool Jacobian: the linear rows the mean of two points', the angular ones the first link's
      const int la = link_index_(tool_.link, "tool link"), lb = link_index_(tool_.second_link, "tool second link");
      add(la, ws.o[la] + ws.R[la] * tool_.offset.translation(), 0.5 * force, moment);
      add(lb, ws.o[lb] + ws.R[lb] * tool_.second_point, 0.5 * force, Eigen::Vector3d::Zero());
    } else {
      const int l = link_index_(e.link, "external wrench link");
      add(l, ws.o[l] + ws.R[l] * e.point, force, moment);
    }
  }
}

void Robot::inverse_dynamics_derivatives(const double* q, const double* qd, const double* qdd,
                                         const std::vector<ExternalWrench>& wrenches, Workspace& ws,
                                         MatN& dtau_dq, MatN& dtau_dqd, MatN& M) const {
  kinematics(q, ws);
  rnea_derivatives_kin_(qd, qdd, ws, dtau_dq, dtau_dqd, M);
  if (!wrenches.empty()) {
    MatN d = MatN::Zero(n_, n_);
    external_torque_derivatives_(wrenches, ws, d);
    dtau_dq -= d;
  }
}

void Robot::forward_dynamics_derivatives(const double* q, const double* qd, const double* tau,
                                         const std::vector<ExternalWrench>& wrenches, Workspace& ws,
                                         MatN& dqdd_dq, MatN& dqdd_dqd, MatN& Minv, VecN* qdd_out) const {
  VecN te, qdd;
  const double* tep = nullptr;
  if (!wrenches.empty()) {
    kinematics(q, ws);
    external_torques(wrenches, ws, te);
    tep = te.data();
  }
  // qdd as forward_dynamics gives it (the same backend, its check of M), then the derivatives there
  forward_dynamics(q, qd, tau, tep, ws, qdd, false);
  // the numeric path left the kinematics of q in ws; generated code computes none
  if (uses_generated()) kinematics(q, ws);
  MatN dq, dqd, M;
  rnea_derivatives_kin_(qd, qdd.data(), ws, dq, dqd, M);
  if (!wrenches.empty()) {
    MatN d = MatN::Zero(n_, n_);
    external_torque_derivatives_(wrenches, ws, d);
    dq -= d;
  }
  const Eigen::LLT<MatN> llt(M);
  Minv = llt.solve(MatN::Identity(n_, n_));
  dqdd_dq.noalias() = -Minv * dq;
  dqdd_dqd.noalias() = -Minv * dqd;
  if (qdd_out) *qdd_out = qdd;
}

void forward_dynamics_derivatives_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU,
                                        int N, double* dqdd_dq, double* dqdd_dqd, double* dqdd_dtau, int threads) {
  if (N <= 0) return;
  const int n = robot.dof();
  // as forward_dynamics_batch: chunks of consecutive states taken by whichever thread is idle from one atomic
  // counter, the calling thread one of the pool, each with its workspace; the first failing row rethrown
  constexpr int kChunk = 64;
  const int chunks = (N + kChunk - 1) / kChunk;
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::max(1, std::min(threads, chunks));
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  std::mutex error_mutex;
  int error_row = N;
  std::exception_ptr error;
  const std::vector<ExternalWrench> none;
  auto work = [&]() {
    Workspace ws;
    MatN A, B, C;
    using RowMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
    for (int c = next++; c < chunks && !failed.load(std::memory_order_relaxed); c = next++) {
      const int end = std::min(N, (c + 1) * kChunk);
      for (int i = c * kChunk; i < end; ++i) {
        const size_t o = static_cast<size_t>(i) * n, oo = o * n;
        try {
          robot.forward_dynamics_derivatives(Q + o, QD + o, TAU + o, none, ws, A, B, C);
        } catch (...) {
          std::lock_guard<std::mutex> lock(error_mutex);
          if (i < error_row) {
            error_row = i;
            error = std::current_exception();
          }
          failed = true;
          break;
        }
        RowMap(dqdd_dq + oo, n, n) = A;
        RowMap(dqdd_dqd + oo, n, n) = B;
        RowMap(dqdd_dtau + oo, n, n) = C;
      }
    }
  };
  if (threads == 1) {
    work();
  } else {
    std::vector<std::thread> pool;
    pool.reserve(threads - 1);
    for (int t = 1; t < threads; ++t) pool.emplace_back(work);
    work();
    for (auto& th : pool) th.join();
  }
  if (error) {
    const std::string row = "state " + std::to_string(error_row) + " (row of q, qd, tau): ";
    try {
      std::rethrow_exception(error);
    } catch (const std::domain_error& e) {
      throw std::domain_error(row + e.what());
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(row + e.what());
    }
  }
}

}  // namespace coopsim
