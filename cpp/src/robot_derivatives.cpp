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
//
// A robot whose generated code carries the derivatives (GeneratedDynamics::derivatives: the symbolic
// model's d(M qdd + b)/dq, db/dqd and M, emitted by coopsim.codegen) takes them from there instead, the
// wrenches' term added as on the recursive path; without wrenches the forward ones come from the
// generated code's own straight-line pass (GeneratedDynamics::forward_derivatives), four states at once
// in the batch (forward_derivatives4).
#include "coopsim/robot.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "batch_rows.hpp"
#include "coopsim/generated.hpp"
#include "internal.hpp"

namespace coopsim {

namespace {

using detail::require;
using V3 = Eigen::Vector3d;
using M3 = Eigen::Matrix3d;

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

// A spatial inertia about the world origin, [[J, skew(h)], [-skew(h), m 1]] (J the inertia about the origin,
// h = m c), and its variation with a velocity v = [w; u], B = (v x*) I - I (v x) = [[T, skew(p)], [-skew(p), 0]]
// with T = K + K^T - h u^T - u h^T + 2 (u . h) 1 (K = skew(w) J) and p = w x h + m u: B is symmetric
// (so beta_k uses B). Sums of these (composite bodies) keep the form: each is 1 + 3 + 3 + 9 + 9 numbers and
// applies to a spatial vector in 3-vector operations.
struct Body {
  double m;
  V3 h, p;
  M3 J, T;
  inline Vec6 inertia(const Vec6& x) const {  // I x
    Vec6 r;
    r.head<3>() = J * x.head<3>() + h.cross(x.tail<3>());
    r.tail<3>() = m * x.tail<3>() - h.cross(x.head<3>());
    return r;
  }
  inline Vec6 variation(const Vec6& x) const {  // B x
    Vec6 r;
    r.head<3>() = T * x.head<3>() + p.cross(x.tail<3>());
    r.tail<3>() = -p.cross(x.head<3>());
    return r;
  }
  void add(const Body& o) {
    m += o.m;
    h += o.h;
    p += o.p;
    J += o.J;
    T += o.T;
  }
};

// On x86-64 the forward derivatives' linear algebra is compiled twice, for the baseline x86-64 and for
// x86-64-v3 (AVX2, FMA), as the generated code is; the loader picks the one this CPU runs.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(COOPSIM_GENERATED_BASELINE_ONLY)
#define COOPSIM_DERIVATIVES_TARGETS __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define COOPSIM_DERIVATIVES_TARGETS
#endif

// The forward dynamics' derivatives from the inverse ones: [X Y Minv] = M^-1 [-A -B 1] with M symmetric
// positive definite (n x n, column-major, as A, B and the results): one Cholesky factorisation and the
// substitutions of the 3n right-hand sides at once, each row a vector of 3n numbers (vectorised across the
// columns), the size known at compile time. false where a pivot is lost (solve_spd's rule).
template <int N>
inline __attribute__((always_inline)) bool forward_from_inverse_fixed(const double* M, const double* A,
                                                                      const double* B, double* Minv, double* X,
                                                                      double* Y) {
  constexpr int W = 3 * N;
  double L[N][N], r[N];
  for (int j = 0; j < N; ++j) {
    const double d0 = M[j + j * N];
    double d = d0;
    for (int k = 0; k < j; ++k) d -= L[j][k] * L[j][k];
    if (!(d > 1e-13 * d0)) return false;
    d = std::sqrt(d);
    L[j][j] = d;
    r[j] = 1.0 / d;
    for (int i = j + 1; i < N; ++i) {
      double v = M[i + j * N];
      for (int k = 0; k < j; ++k) v -= L[i][k] * L[j][k];
      L[i][j] = v * r[j];
    }
  }
  alignas(32) double Z[N][W];
  for (int i = 0; i < N; ++i)
    for (int c = 0; c < N; ++c) {
      Z[i][c] = -A[i + c * N];
      Z[i][N + c] = -B[i + c * N];
      Z[i][2 * N + c] = i == c ? 1.0 : 0.0;
    }
  for (int i = 0; i < N; ++i) {  // L y = z
    for (int k = 0; k < i; ++k)
      for (int c = 0; c < W; ++c) Z[i][c] -= L[i][k] * Z[k][c];
    for (int c = 0; c < W; ++c) Z[i][c] *= r[i];
  }
  for (int i = N - 1; i >= 0; --i) {  // L^T x = y
    for (int k = i + 1; k < N; ++k)
      for (int c = 0; c < W; ++c) Z[i][c] -= L[k][i] * Z[k][c];
    for (int c = 0; c < W; ++c) Z[i][c] *= r[i];
  }
  for (int c = 0; c < N; ++c)
    for (int i = 0; i < N; ++i) {
      X[i + c * N] = Z[i][c];
      Y[i + c * N] = Z[i][N + c];
      Minv[i + c * N] = Z[i][2 * N + c];
    }
  return true;
}

template <int... Ns>
inline __attribute__((always_inline)) bool forward_from_inverse_sizes(int n, const double* M, const double* A,
                                                                      const double* B, double* Minv, double* X,
                                                                      double* Y, std::integer_sequence<int, Ns...>) {
  bool ok = false;
  ((n == Ns + 1 ? (ok = forward_from_inverse_fixed<Ns + 1>(M, A, B, Minv, X, Y), true) : false) || ...);
  return ok;
}

COOPSIM_DERIVATIVES_TARGETS
bool forward_from_inverse_n(int n, const double* M, const double* A, const double* B, double* Minv, double* X,
                            double* Y) {
  return forward_from_inverse_sizes(n, M, A, B, Minv, X, Y, std::make_integer_sequence<int, kMaxDof>());
}

bool forward_from_inverse(const MatN& M, const MatN& A, const MatN& B, MatN& Minv, MatN& X, MatN& Y) {
  const int n = static_cast<int>(M.rows());
  Minv.resize(n, n);
  X.resize(n, n);
  Y.resize(n, n);
  return forward_from_inverse_n(n, M.data(), A.data(), B.data(), Minv.data(), X.data(), Y.data());
}

}  // namespace

bool Robot::rnea_derivatives_kin_(const double* qd, const double* qdd, const double* tau, const double* tau_ext,
                                  const Workspace& ws, MatN& dtau_dq, MatN& dtau_dqd, MatN& M, VecN& qdd_out) const {
  const int n = n_;
  std::array<Vec6, kMaxDof> S, Sd, Psi, f, mom, da, F, alpha;
  std::array<Body, kMaxDof> body;
  std::array<double, kMaxDof> own_m;  // each link's own inertia, before the composites are summed
  std::array<V3, kMaxDof> own_h;
  std::array<M3, kMaxDof> own_J;
  // forward: velocities, the accelerations without qdd (gravity as a base acceleration), each link's
  // inertia and variation, momentum and force at qdd = 0
  Vec6 v = Vec6::Zero(), a = Vec6::Zero();
  a.tail<3>() = -gravity_;
  for (int k = 0; k < n; ++k) {
    const V3 z = ws.R[k].col(2);
    if (links_[k].type == JointType::Revolute) S[k] << z, ws.o[k].cross(z);
    else S[k] << V3::Zero(), z;
    Sd[k] = cross_m(v, S[k]);
    Psi[k] = cross_m(a, S[k]) + cross_m(v, Sd[k]);
    v += S[k] * qd[k];
    a += Sd[k] * qd[k];
    Body& b = body[k];
    b.m = links_[k].mass;
    const V3& c = ws.c[k];
    b.h = b.m * c;
    // J = I_c + m (|c|^2 1 - c c^T)
    b.J = ws.Iw[k] - b.h * c.transpose();
    b.J.diagonal().array() += b.h.dot(c);
    const V3 w = v.head<3>(), u = v.tail<3>();
    M3 K;
    for (int col = 0; col < 3; ++col) K.col(col) = w.cross(b.J.col(col));
    b.T = K + K.transpose() - b.h * u.transpose() - u * b.h.transpose();
    b.T.diagonal().array() += 2.0 * u.dot(b.h);
    b.p = w.cross(b.h) + b.m * u;
    own_m[k] = b.m;
    own_h[k] = b.h;
    own_J[k] = b.J;
    mom[k] = b.inertia(v);
    f[k] = b.inertia(a) + cross_f(v, mom[k]);
  }
  // backward: composites from the tip; alpha_k = Ic_k S_k gives M; the bias at qdd = 0
  for (int k = n - 1; k >= 0; --k) {
    if (k < n - 1) {
      body[k].add(body[k + 1]);
      mom[k] += mom[k + 1];
      f[k] += f[k + 1];
    }
    alpha[k] = body[k].inertia(S[k]);
  }
  M.resize(n, n);
  for (int k = 0; k < n; ++k) {
    for (int j = 0; j <= k; ++j) M(j, k) = S[j].dot(alpha[k]);
    for (int j = k + 1; j < n; ++j) M(j, k) = S[k].dot(alpha[j]);
    M(k, k) += links_[k].armature;
  }
  VecN acc(n);
  if (tau) {
    // forward dynamics: M qdd = tau + tau_ext - bias (Cholesky, forward_dynamics' pivot rule)
    VecN rhs(n);
    for (int k = 0; k < n; ++k) {
      const Link& L = links_[k];
      double bias = S[k].dot(f[k]) + L.friction * qd[k];
      if (L.coulomb > 0) bias += L.coulomb * std::tanh(qd[k] / L.coulomb_width);
      rhs[k] = tau[k] - bias + (tau_ext ? tau_ext[k] : 0.0);
    }
    MatN L = M;
    if (!solve_spd(L, rhs, acc)) return false;
  } else {
    acc = qdd ? VecN(Eigen::Map<const VecN>(qdd, n)) : VecN(VecN::Zero(n));
  }
  qdd_out = acc;
  // the accelerations' part of qdd: da_k = sum_{j <= k} S_j qdd_j, into Psi and (through the links'
  // inertias I_i da_i, summed from the tip) into the forces F_k
  Vec6 d = Vec6::Zero();
  for (int k = 0; k < n; ++k) {
    Psi[k] += cross_m(d, S[k]);
    d += S[k] * acc[k];
    da[k] = d;
  }
  Vec6 sum = Vec6::Zero();
  for (int k = n - 1; k >= 0; --k) {
    const Vec6& x = da[k];
    sum.head<3>() += own_J[k] * x.head<3>() + own_h[k].cross(x.tail<3>());
    sum.tail<3>() += own_m[k] * x.tail<3>() - own_h[k].cross(x.head<3>());
    F[k] = f[k] + sum;
  }
  dtau_dq.resize(n, n);
  dtau_dqd.resize(n, n);
  for (int k = 0; k < n; ++k) {
    const Body& b = body[k];
    const Vec6 alpha_k = alpha[k];
    const Vec6 beta_k = b.variation(S[k]) - cross_f(S[k], mom[k]);
    const Vec6 u = cross_f(S[k], F[k]) + b.inertia(Psi[k]) + cross_f(Sd[k], mom[k]) + b.variation(Sd[k]);
    const Vec6 w = 2.0 * b.inertia(Sd[k]) + b.variation(S[k]) + cross_f(S[k], mom[k]);
    // column k on and above the diagonal; row k left of it
    for (int j = 0; j <= k; ++j) {
      dtau_dq(j, k) = S[j].dot(u);
      dtau_dqd(j, k) = S[j].dot(w);
    }
    for (int j = 0; j < k; ++j) {
      dtau_dq(k, j) = Psi[j].dot(alpha_k) + Sd[j].dot(beta_k);
      dtau_dqd(k, j) = 2.0 * Sd[j].dot(alpha_k) + S[j].dot(beta_k);
    }
  }
  for (int k = 0; k < n; ++k) {
    const Link& L = links_[k];
    double dd = L.friction;
    if (L.coulomb > 0) {
      const double t = std::tanh(qd[k] / L.coulomb_width);
      dd += L.coulomb / L.coulomb_width * (1.0 - t * t);
    }
    dtau_dqd(k, k) += dd;
  }
  return true;
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
  if (uses_generated() && generated_->derivatives) {
    dtau_dq.resize(n_, n_);
    dtau_dqd.resize(n_, n_);
    M.resize(n_, n_);
    generated_->derivatives(gen_params_.data(), q, qd, qdd, dtau_dq.data(), dtau_dqd.data(), M.data());
    if (!wrenches.empty()) {
      kinematics(q, ws, false);  // the frames, where the wrenches act
      MatN d = MatN::Zero(n_, n_);
      external_torque_derivatives_(wrenches, ws, d);
      dtau_dq -= d;
    }
    return;
  }
  kinematics(q, ws);
  VecN acc;
  rnea_derivatives_kin_(qd, qdd, nullptr, nullptr, ws, dtau_dq, dtau_dqd, M, acc);
  if (!wrenches.empty()) {
    MatN d = MatN::Zero(n_, n_);
    external_torque_derivatives_(wrenches, ws, d);
    dtau_dq -= d;
  }
}

void Robot::forward_dynamics_derivatives(const double* q, const double* qd, const double* tau,
                                         const std::vector<ExternalWrench>& wrenches, Workspace& ws,
                                         MatN& dqdd_dq, MatN& dqdd_dqd, MatN& Minv, VecN* qdd_out,
                                         const double* tau_ext) const {
  const bool gen = uses_generated() && generated_->derivatives && generated_->dynamics;
  if (gen && wrenches.empty() && generated_->forward_derivatives) {
    // the generated code's one straight-line pass (dynamics, LDL^T factor, qdd, derivatives, 3n solves)
    const double* t = tau;
    VecN tt;
    if (tau_ext) {
      tt = Eigen::Map<const VecN>(tau, n_) + Eigen::Map<const VecN>(tau_ext, n_);
      t = tt.data();
    }
    dqdd_dq.resize(n_, n_);
    dqdd_dqd.resize(n_, n_);
    Minv.resize(n_, n_);
    if (qdd_out) qdd_out->resize(n_);
    if (generated_->forward_derivatives(gen_params_.data(), q, qd, t, dqdd_dq.data(), dqdd_dqd.data(), Minv.data(),
                                        qdd_out ? qdd_out->data() : nullptr)) {
      dqdd_dq.transposeInPlace();  // written row-major (numpy's layout)
      dqdd_dqd.transposeInPlace();
      Minv.transposeInPlace();
      return;
    }
    // a pivot lost: the path below raises forward_dynamics' own error
  }
  if (!gen) kinematics(q, ws);
  else if (!wrenches.empty()) kinematics(q, ws, false);  // the frames, where the wrenches act
  VecN te, qdd;
  const double* tep = tau_ext;
  if (!wrenches.empty()) {
    external_torques(wrenches, ws, te);
    if (tau_ext) te += Eigen::Map<const VecN>(tau_ext, n_);
    tep = te.data();
  }
  MatN dq, dqd, M;
  bool ok;
  if (gen) {
    // qdd = FD(q, qd, tau) as forward_dynamics computes it, then the generated derivatives at that qdd
    const double* p = gen_params_.data();
    M.resize(n_, n_);
    qdd.resize(n_);
    VecN h(n_);
    generated_->dynamics(p, q, qd, M.data(), h.data());
    qdd = Eigen::Map<const VecN>(tau, n_) - h;
    if (tep) qdd += Eigen::Map<const VecN>(tep, n_);
    if (generated_->solve) {
      ok = generated_->solve(M.data(), qdd.data());
    } else {
      MatN L = M;
      const VecN rhs = qdd;
      ok = solve_spd(L, rhs, qdd);
    }
    if (ok) {
      dq.resize(n_, n_);
      dqd.resize(n_, n_);
      generated_->derivatives(p, q, qd, qdd.data(), dq.data(), dqd.data(), M.data());
    }
  } else {
    // one pass for M, the bias and qdd = M^-1 (tau + tau_ext - bias), the derivatives at that qdd
    ok = rnea_derivatives_kin_(qd, nullptr, tau, tep, ws, dq, dqd, M, qdd);
  }
  if (ok && !wrenches.empty()) {
    MatN d = MatN::Zero(n_, n_);
    external_torque_derivatives_(wrenches, ws, d);
    dq -= d;
  }
  if (!ok || !forward_from_inverse(M, dq, dqd, Minv, dqdd_dq, dqdd_dqd)) {
    forward_dynamics(q, qd, tau, tep, ws, qdd, false);  // raises forward_dynamics' own error
    throw std::domain_error("forward_dynamics_derivatives: the mass matrix is not positive definite");
  }
  if (qdd_out) *qdd_out = qdd;
}

void Robot::forward_dynamics_derivatives_rows(const double* q, const double* qd, const double* tau, double* dqdd_dq,
                                              double* dqdd_dqd, double* Minv) const {
  if (uses_generated() && generated_->derivatives && generated_->dynamics && generated_->forward_derivatives &&
      generated_->forward_derivatives(gen_params_.data(), q, qd, tau, dqdd_dq, dqdd_dqd, Minv, nullptr))
    return;
  Workspace ws;
  MatN a, b, c;
  forward_dynamics_derivatives(q, qd, tau, {}, ws, a, b, c);
  using RowMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  RowMap(dqdd_dq, n_, n_) = a;
  RowMap(dqdd_dqd, n_, n_) = b;
  RowMap(Minv, n_, n_) = c;
}

void forward_dynamics_derivatives_batch(const Robot& robot, const double* Q, const double* QD, const double* TAU,
                                        int N, double* dqdd_dq, double* dqdd_dqd, double* dqdd_dtau, int threads) {
  const int n = robot.dof();
  // generated code with the four-lane pass: four consecutive states at once, written straight into the
  // rows of the results; a state whose group of four cannot (the last ones, a pivot lost in a lane) by the
  // single-state path, which names it when it fails
  const GeneratedDynamics* gen = robot.uses_generated() ? robot.generated().get() : nullptr;
  const auto four = gen && gen->derivatives && gen->constants ? gen->forward_derivatives4 : nullptr;
  std::vector<double> p;
  if (four) {
    p = robot.parameter_vector();
    const size_t base = p.size();
    p.resize(base + gen->constant_count);
    gen->constants(p.data(), p.data() + base);
  }
  struct State {
    Workspace ws;  // the single-state path's, one per thread: nothing allocated per state
    MatN A, B, C;
    int done = 0;  // the states before this one are written (by a group of four)
  };
  using RowMap = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  const std::vector<ExternalWrench> none;
  // as forward_dynamics_batch (batch_rows.hpp), in chunks of 64 states (a multiple of four: a group lies
  // in one chunk, done by one thread in order)
  detail::batch_rows(N, 64, threads, [] { return State(); }, [&](State& st, int i) {
    if (i < st.done) return;
    const size_t o = static_cast<size_t>(i) * n, oo = o * n;
    if (four && i % 4 == 0 && i + 4 <= N &&
        four(p.data(), Q + o, QD + o, TAU + o, dqdd_dq + oo, dqdd_dqd + oo, dqdd_dtau + oo)) {
      st.done = i + 4;
      return;
    }
    robot.forward_dynamics_derivatives(Q + o, QD + o, TAU + o, none, st.ws, st.A, st.B, st.C);
    RowMap(dqdd_dq + oo, n, n) = st.A;
    RowMap(dqdd_dqd + oo, n, n) = st.B;
    RowMap(dqdd_dtau + oo, n, n) = st.C;
  });
}

}  // namespace coopsim
