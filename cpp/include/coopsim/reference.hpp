// A joint-space reference that controllers track: desired q, qd, qdd at any
// time. Implementations are immutable after construction, so one reference
// may be evaluated from several threads at once.
#pragma once

#include <stdexcept>
#include <string>

#include "coopsim/checks.hpp"
#include "coopsim/robot.hpp"

namespace coopsim {

class Reference {
 public:
  virtual ~Reference() = default;
  virtual int dof() const = 0;
  virtual double t_start() const = 0;  // s
  virtual double t_end() const = 0;    // s; after it the reference holds its end point
  // Writes n values each to q (rad or m), qd (per s) and qdd (per s^2); qd or
  // qdd may be null when not wanted.
  virtual void evaluate(double t, double* q, double* qd, double* qdd) const = 0;
};

// A constant set-point: q_ref = q, qd_ref = qdd_ref = 0 at all times.
class ConstantReference : public Reference {
 public:
  explicit ConstantReference(VecN q) : q_(std::move(q)) {}
  // q: (n,) finite, 1 <= n <= kMaxDof; std::invalid_argument naming q otherwise.
  explicit ConstantReference(const Array& q) {
    check_shape(q, {-1}, "q");
    if (q.shape[0] < 1 || q.shape[0] > kMaxDof)
      throw std::invalid_argument("q must have 1 to " + std::to_string(kMaxDof) + " entries");
    check_finite(q, "q");
    q_ = Eigen::Map<const Eigen::VectorXd>(q.values.data(), q.shape[0]);
  }
  int dof() const override { return static_cast<int>(q_.size()); }
  double t_start() const override { return 0.0; }
  double t_end() const override { return 0.0; }
  void evaluate(double, double* q, double* qd, double* qdd) const override {
    for (int i = 0; i < q_.size(); ++i) {
      if (q) q[i] = q_[i];
      if (qd) qd[i] = 0.0;
      if (qdd) qdd[i] = 0.0;
    }
  }
  const VecN& point() const { return q_; }

 private:
  VecN q_;
};

}  // namespace coopsim
