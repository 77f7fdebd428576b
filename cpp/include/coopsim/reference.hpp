// A joint-space reference that controllers track: desired q, qd, qdd at any
// time. Implementations are immutable after construction, so one reference
// may be evaluated from several threads at once.
#pragma once

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

}  // namespace coopsim
