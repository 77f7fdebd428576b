#include "coopsim/controller.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace coopsim {

namespace {

void check_gains(const Eigen::VectorXd& g, const char* name, bool allow_empty = false) {
  if (g.size() == 0) {
    if (allow_empty) return;
    throw std::invalid_argument(std::string(name) + " must have at least one value");
  }
  if (g.size() > kMaxDof)
    throw std::invalid_argument(std::string(name) + " has " + std::to_string(g.size()) + " values, more than " +
                                std::to_string(kMaxDof) + " joints");
  for (Eigen::Index i = 0; i < g.size(); ++i) {
    if (!std::isfinite(g[i])) throw std::invalid_argument(std::string(name) + " must be finite (got NaN or inf)");
    if (g[i] < 0)
      throw std::invalid_argument(std::string(name) + " must be >= 0, got " + std::to_string(g[i]) + " at joint " +
                                  std::to_string(i + 1));
  }
}

void check_size(const Eigen::VectorXd& g, const char* name, const Robot& robot) {
  if (g.size() != 1 && g.size() != robot.dof())
    throw std::invalid_argument("wrong size for " + std::string(name) + ": expected 1 or " +
                                std::to_string(robot.dof()) + " values for robot '" + robot.name() + "', got " +
                                std::to_string(g.size()));
}

void check_model(const std::shared_ptr<const Robot>& model, const Robot& robot) {
  if (model && model->dof() != robot.dof())
    throw std::invalid_argument("model has " + std::to_string(model->dof()) + " joints but robot '" + robot.name() +
                                "' has " + std::to_string(robot.dof()));
}

// the model a controller takes G(q) from: its own, else the robot's; null without gravity compensation
std::shared_ptr<const Robot> gravity_model(bool on, const std::shared_ptr<const Robot>& model, const Robot& robot) {
  return on ? (model ? model : std::make_shared<const Robot>(robot)) : nullptr;
}

// (1,) broadcasts to every joint
VecN expand(const Eigen::VectorXd& g, int n) {
  VecN out(n);
  for (int i = 0; i < n; ++i) out[i] = g.size() == 1 ? g[0] : g[i];
  return out;
}

}  // namespace

VecN compute(Controller& controller, double t, const Array& q, const Array& qd, const Array& q_ref,
             const Array& qd_ref, const Array& qdd_ref, const Array* wrench) {
  if (q.ndim() != 1)
    throw std::invalid_argument("wrong shape for q: expected (n,), got " + shape_string(q.shape.data(), q.ndim()));
  const int n = static_cast<int>(q.shape[0]);
  if (n < 1 || n > kMaxDof) throw std::invalid_argument("q must have 1.." + std::to_string(kMaxDof) + " values");
  const Array* in[5] = {&q, &qd, &q_ref, &qd_ref, &qdd_ref};
  const char* names[5] = {"q", "qd", "q_ref", "qd_ref", "qdd_ref"};
  for (int i = 0; i < 5; ++i) {
    check_shape(*in[i], {n}, names[i]);
    check_finite(*in[i], names[i]);
  }
  check_finite(t, "t");
  if (wrench) {
    check_shape(*wrench, {6}, "wrench");
    check_finite(*wrench, "wrench");
  }
  VecN tau(n);
  controller.compute(ControlInput{n, t, q.values.data(), qd.values.data(), q_ref.values.data(),
                                  qd_ref.values.data(), qdd_ref.values.data(),
                                  wrench ? wrench->values.data() : nullptr},
                     tau.data());
  return tau;
}

Eigen::VectorXd gains(const Array& a, const char* name) {
  if (a.ndim() > 1)
    throw std::invalid_argument(std::string("wrong shape for ") + name + ": expected a scalar or (n,), got " +
                                shape_string(a.shape.data(), a.ndim()));
  return Eigen::Map<const Eigen::VectorXd>(a.values.data(), static_cast<Eigen::Index>(a.values.size()));
}

// ---- PID ----

PID::PID(Eigen::VectorXd kp, Eigen::VectorXd ki, Eigen::VectorXd kd, bool gravity_compensation,
         double derivative_filter, Eigen::VectorXd integral_limit, std::shared_ptr<const Robot> model)
    : kp_(std::move(kp)), ki_(std::move(ki)), kd_(std::move(kd)), ilim_(std::move(integral_limit)),
      gravity_(gravity_compensation), tf_(derivative_filter), model_(std::move(model)) {
  check_gains(kp_, "kp");
  check_gains(ki_, "ki");
  check_gains(kd_, "kd");
  check_gains(ilim_, "integral_limit", true);
  if (!std::isfinite(tf_) || tf_ < 0)
    throw std::invalid_argument("derivative_filter must be finite and >= 0 s, got " + std::to_string(tf_));
}

void PID::check(const Robot& robot) const {
  check_size(kp_, "kp", robot);
  check_size(ki_, "ki", robot);
  check_size(kd_, "kd", robot);
  if (ilim_.size()) check_size(ilim_, "integral_limit", robot);
  check_model(model_, robot);
}

void PID::reset(const Robot& robot, double period) {
  check(robot);
  if (!(period > 0) || !std::isfinite(period))
    throw std::invalid_argument("period must be finite and > 0 s");
  n_ = robot.dof();
  h_ = period;
  Kp_ = expand(kp_, n_);
  Ki_ = expand(ki_, n_);
  Kd_ = expand(kd_, n_);
  tau_max_ = robot.tau_max();
  Ilim_ = ilim_.size() ? expand(ilim_, n_) : tau_max_;
  gmodel_ = gravity_model(gravity_, model_, robot);
  integral_ = VecN::Zero(n_);
  v_ = VecN::Zero(n_);
  q_prev_ = VecN::Zero(n_);
  g_ = VecN::Zero(n_);
  first_ = true;
}

void PID::compute(const ControlInput& in, double* tau) {
  if (n_ == 0 || in.n != n_) throw std::logic_error("PID.compute called before reset() for this robot");
  const int n = n_;
  // filtered derivative of the measured position
  if (first_) {
    for (int i = 0; i < n; ++i) v_[i] = in.qd[i];
    first_ = false;
  } else {
    const double a = tf_ / (tf_ + h_);
    for (int i = 0; i < n; ++i) v_[i] = a * v_[i] + (1.0 - a) * ((in.q[i] - q_prev_[i]) / h_);
  }
  for (int i = 0; i < n; ++i) q_prev_[i] = in.q[i];
  if (gmodel_) gmodel_->gravity(in.q, workspace(in, *gmodel_, ws_), g_);
  for (int i = 0; i < n; ++i) {
    const double e = in.q_ref[i] - in.q[i];
    double u0 = Kp_[i] * e + Kd_[i] * (in.qd_ref[i] - v_[i]);
    if (gmodel_) u0 += g_[i];
    double I = integral_[i] + e * h_;
    // anti-windup: do not integrate further into saturation
    const double u = u0 + Ki_[i] * I;
    if ((u > tau_max_[i] && e > 0) || (u < -tau_max_[i] && e < 0)) I = integral_[i];
    if (Ki_[i] > 0) {
      const double imax = Ilim_[i] / Ki_[i];
      if (I > imax) I = imax;
      else if (I < -imax) I = -imax;
    }
    integral_[i] = I;
    tau[i] = u0 + Ki_[i] * I;
  }
  saturate(n, tau_max_.data(), tau);
}

// ---- computed torque ----

ComputedTorque::ComputedTorque(Eigen::VectorXd kp, Eigen::VectorXd kd, std::shared_ptr<const Robot> model)
    : kp_(std::move(kp)), kd_(std::move(kd)), model_(std::move(model)) {
  check_gains(kp_, "kp");
  check_gains(kd_, "kd");
}

void ComputedTorque::check(const Robot& robot) const {
  check_size(kp_, "kp", robot);
  check_size(kd_, "kd", robot);
  check_model(model_, robot);
}

void ComputedTorque::reset(const Robot& robot, double period) {
  check(robot);
  n_ = robot.dof();
  Kp_ = expand(kp_, n_);
  Kd_ = expand(kd_, n_);
  tau_max_ = robot.tau_max();
  run_model_ = model_ ? model_ : std::make_shared<const Robot>(robot);
  v_ = VecN::Zero(n_);
  out_ = VecN::Zero(n_);
}

void ComputedTorque::compute(const ControlInput& in, double* tau) {
  if (n_ == 0 || in.n != n_) throw std::logic_error("ComputedTorque.compute called before reset() for this robot");
  for (int i = 0; i < n_; ++i)
    v_[i] = in.qdd_ref[i] + Kd_[i] * (in.qd_ref[i] - in.qd[i]) + Kp_[i] * (in.q_ref[i] - in.q[i]);
  // M v + C + G + K qd in one Newton-Euler pass
  run_model_->rnea(in.q, in.qd, v_.data(), workspace(in, *run_model_, ws_), out_, 1.0, true);
  for (int i = 0; i < n_; ++i) tau[i] = out_[i];
  saturate(n_, tau_max_.data(), tau);
}

}  // namespace coopsim

// ---- linearisations (Controller::linearize; linearize.hpp closes the loop with them) ----

namespace coopsim {

namespace {

// zero the rows of a saturated output (its derivative is zero past the limit)
void saturated_rows(const VecN& tau_max, ControllerJacobians& J) {
  for (int i = 0; i < J.tau.size(); ++i) {
    if (std::abs(J.tau[i]) <= tau_max[i]) continue;
    J.tau[i] = J.tau[i] > 0 ? tau_max[i] : -tau_max[i];
    J.dtau_dq.row(i).setZero();
    J.dtau_dqd.row(i).setZero();
    if (J.dtau_dc.cols()) J.dtau_dc.row(i).setZero();
  }
}

// dG/dq (n, n) of `model` at q: its inverse dynamics' q-derivative at rest (friction has none in q)
MatN gravity_derivative(const Robot& model, const double* q, Workspace& ws) {
  const VecN zero = VecN::Zero(model.dof());
  MatN dg, unused_dqd, unused_M;
  model.inverse_dynamics_derivatives(q, zero.data(), zero.data(), {}, ws, dg, unused_dqd, unused_M);
  return dg;
}

// a law without internal state (m = 0)
void stateless(int n, ControllerJacobians& J) {
  J.c.resize(0);
  J.c_next.resize(0);
  J.states.clear();
  J.dtau_dc = Eigen::MatrixXd::Zero(n, 0);
  J.dc_dq = Eigen::MatrixXd::Zero(0, n);
  J.dc_dqd = Eigen::MatrixXd::Zero(0, n);
  J.dc_dc = Eigen::MatrixXd::Zero(0, 0);
}

}  // namespace

bool PID::linearize(const Robot& robot, double period, const ControlInput& in, ControllerJacobians& J) const {
  check(robot);
  const int n = robot.dof();
  const bool ran = n_ == n && !first_;
  if (ran && std::abs(h_ - period) > 1e-12 * period)
    throw std::invalid_argument("the PID ran with a period of " + std::to_string(h_) + " s, not the model's " +
                                std::to_string(period) + " s");
  const double h = period;
  const VecN Kp = expand(kp_, n), Ki = expand(ki_, n), Kd = expand(kd_, n), tau_max = robot.tau_max();
  const VecN Ilim = ilim_.size() ? expand(ilim_, n) : tau_max;
  Eigen::VectorXd I = ran ? Eigen::VectorXd(integral_) : Eigen::VectorXd::Zero(n), v(n), qp(n);
  for (int i = 0; i < n; ++i) {
    v[i] = ran ? v_[i] : in.qd[i];
    qp[i] = ran ? q_prev_[i] : in.q[i] - h * in.qd[i];
  }
  // G(q) and its derivative, of the model the run would use
  const std::shared_ptr<const Robot> gm = gravity_model(gravity_, model_, robot);
  VecN g = VecN::Zero(n);
  MatN dg = MatN::Zero(n, n);
  if (gm) {
    Workspace ws;
    gm->gravity(in.q, ws, g);
    dg = gravity_derivative(*gm, in.q, ws);
  }
  const int m = 3 * n;
  J.c.resize(m);
  J.c << I, v, qp;
  J.states.clear();
  for (const char* part : {"integral", "velocity_estimate", "q_previous"})
    for (int i = 0; i < n; ++i) J.states.push_back(std::string("pid.") + part + std::to_string(i));
  J.tau.resize(n);
  J.c_next.resize(m);
  J.dtau_dq = dg;
  J.dtau_dqd = Eigen::MatrixXd::Zero(n, n);
  J.dtau_dc = Eigen::MatrixXd::Zero(n, m);
  J.dc_dq = Eigen::MatrixXd::Zero(m, n);
  J.dc_dqd = Eigen::MatrixXd::Zero(m, n);
  J.dc_dc = Eigen::MatrixXd::Zero(m, m);
  const double a = tf_ / (tf_ + h);
  for (int i = 0; i < n; ++i) {
    const double vn = a * v[i] + (1.0 - a) * (in.q[i] - qp[i]) / h;  // v+ (compute's filter)
    const double e = in.q_ref[i] - in.q[i];
    const double u0 = Kp[i] * e + Kd[i] * (in.qd_ref[i] - vn) + g[i];
    // the integral: integrating (dI+/dI = 1, dI+/dq = -h), held by the anti-windup (1, 0), or at its clamp (0, 0)
    double In = I[i] + e * h, dI_dI = 1.0, dI_dq = -h;
    const double u = u0 + Ki[i] * In;
    if ((u > tau_max[i] && e > 0) || (u < -tau_max[i] && e < 0)) {
      In = I[i];
      dI_dq = 0.0;
    }
    if (Ki[i] > 0 && std::abs(In) > Ilim[i] / Ki[i]) {
      In = In > 0 ? Ilim[i] / Ki[i] : -Ilim[i] / Ki[i];
      dI_dI = dI_dq = 0.0;
    }
    J.tau[i] = u0 + Ki[i] * In;
    J.c_next[i] = In;
    J.c_next[n + i] = vn;
    J.c_next[2 * n + i] = in.q[i];
    const double dv_dq = (1.0 - a) / h;
    J.dtau_dq(i, i) += -Kp[i] - Kd[i] * dv_dq + Ki[i] * dI_dq;
    J.dtau_dc(i, i) = Ki[i] * dI_dI;           // integral
    J.dtau_dc(i, n + i) = -Kd[i] * a;          // velocity estimate
    J.dtau_dc(i, 2 * n + i) = Kd[i] * dv_dq;   // last q
    J.dc_dq(i, i) = dI_dq;
    J.dc_dq(n + i, i) = dv_dq;
    J.dc_dq(2 * n + i, i) = 1.0;
    J.dc_dc(i, i) = dI_dI;
    J.dc_dc(n + i, n + i) = a;
    J.dc_dc(n + i, 2 * n + i) = -dv_dq;
  }
  saturated_rows(tau_max, J);
  return true;
}

bool ComputedTorque::linearize(const Robot& robot, double, const ControlInput& in, ControllerJacobians& J) const {
  check(robot);
  const int n = robot.dof();
  const VecN Kp = expand(kp_, n), Kd = expand(kd_, n);
  const Robot& model = model_ ? *model_ : robot;
  VecN v(n);
  for (int i = 0; i < n; ++i) v[i] = in.qdd_ref[i] + Kd[i] * (in.qd_ref[i] - in.qd[i]) + Kp[i] * (in.q_ref[i] - in.q[i]);
  Workspace ws;
  MatN M, dq, dqd;
  VecN tau;
  model.inverse_dynamics_derivatives(in.q, in.qd, v.data(), {}, ws, dq, dqd, M);
  model.rnea(in.q, in.qd, v.data(), ws, tau, 1.0, true);
  J.tau = tau;
  J.dtau_dq = dq - M * Kp.asDiagonal();
  J.dtau_dqd = dqd - M * Kd.asDiagonal();
  stateless(n, J);
  saturated_rows(robot.tau_max(), J);
  return true;
}

// ---- state feedback ----

StateFeedback::StateFeedback(Eigen::MatrixXd K, Eigen::VectorXd tau0, bool gravity_compensation,
                             std::shared_ptr<const Robot> model)
    : K_(std::move(K)), tau0_(std::move(tau0)), gravity_(gravity_compensation), model_(std::move(model)) {
  if (K_.rows() < 1 || K_.rows() > kMaxDof || K_.cols() != 2 * K_.rows())
    throw std::invalid_argument("wrong shape for K: expected (n, 2n) with 1 <= n <= " + std::to_string(kMaxDof) +
                                ", got (" + std::to_string(K_.rows()) + ", " + std::to_string(K_.cols()) + ")");
  if (!K_.allFinite()) throw std::invalid_argument("K must be finite (got NaN or inf)");
  if (tau0_.size() && tau0_.size() != K_.rows())
    throw std::invalid_argument("wrong shape for tau0: expected (" + std::to_string(K_.rows()) + ",), got (" +
                                std::to_string(tau0_.size()) + ",)");
  if (!tau0_.allFinite()) throw std::invalid_argument("tau0 must be finite (got NaN or inf)");
}

void StateFeedback::check(const Robot& robot) const {
  if (K_.rows() != robot.dof())
    throw std::invalid_argument("wrong size for K: expected (" + std::to_string(robot.dof()) + ", " +
                                std::to_string(2 * robot.dof()) + ") for robot '" + robot.name() + "', got (" +
                                std::to_string(K_.rows()) + ", " + std::to_string(K_.cols()) + ")");
  check_model(model_, robot);
}

void StateFeedback::reset(const Robot& robot, double) {
  check(robot);
  n_ = robot.dof();
  tau_max_ = robot.tau_max();
  gmodel_ = gravity_model(gravity_, model_, robot);
  out_ = Eigen::VectorXd::Zero(n_);
}

void StateFeedback::law_(const Robot* gm, const double* q, const double* qd, const double* q_ref,
                         const double* qd_ref, Workspace& ws, Eigen::VectorXd& tau) const {
  const int n = static_cast<int>(K_.rows());
  Eigen::VectorXd e(2 * n);
  for (int i = 0; i < n; ++i) {
    e[i] = q[i] - q_ref[i];
    e[n + i] = qd[i] - qd_ref[i];
  }
  tau = -K_ * e;
  if (tau0_.size()) tau += tau0_;
  if (gm) {
    VecN g;
    gm->gravity(q, ws, g);
    tau += g;
  }
}

void StateFeedback::compute(const ControlInput& in, double* tau) {
  if (n_ == 0 || in.n != n_) throw std::logic_error("StateFeedback.compute called before reset() for this robot");
  law_(gmodel_.get(), in.q, in.qd, in.q_ref, in.qd_ref, gmodel_ ? workspace(in, *gmodel_, ws_) : ws_, out_);
  for (int i = 0; i < n_; ++i) tau[i] = out_[i];
  saturate(n_, tau_max_.data(), tau);
}

bool StateFeedback::linearize(const Robot& robot, double, const ControlInput& in, ControllerJacobians& J) const {
  check(robot);
  const int n = robot.dof();
  const std::shared_ptr<const Robot> gm = gravity_model(gravity_, model_, robot);
  Workspace ws;
  law_(gm.get(), in.q, in.qd, in.q_ref, in.qd_ref, ws, J.tau);
  J.dtau_dq = -K_.leftCols(n);
  J.dtau_dqd = -K_.rightCols(n);
  if (gm) J.dtau_dq += gravity_derivative(*gm, in.q, ws);
  stateless(n, J);
  saturated_rows(robot.tau_max(), J);
  return true;
}

}  // namespace coopsim
