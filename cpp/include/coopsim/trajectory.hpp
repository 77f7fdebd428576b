// Joint trajectories of piecewise cubic polynomials (the paper's eqs. 6-8).
//
// Via-points q_i = Q(t_i), i = 0..N-1 (N >= 2, strictly increasing times),
// for n joints. Segment k (t_k <= t <= t_{k+1}) of joint j is a cubic in the
// local time tau = t - t_k:
//     p(tau) = c0 + c1 tau + c2 tau^2 + c3 tau^3,
// meeting the four Hermite conditions p(0) = q_k, p'(0) = v_k, p(h) = q_{k+1},
// p'(h) = v_{k+1}, h = t_{k+1} - t_k. (The paper's eq. 8 uses absolute time,
// which is ill-conditioned and misprinted; local time is exact.) Position and
// velocity are therefore continuous at every knot.
//
// Knot velocities v_i come from, in this order of precedence:
// - the caller (all N of them), or
// - KnotVelocities::Spline: the C^2-continuous cubic spline through the points
//   with v_0 and v_{N-1} given (clamped ends), acceleration continuous too;
// - KnotVelocities::Heuristic (default): ends v_0, v_{N-1} given (default 0);
//   interior v_i = (s_{i-1} + s_i) / 2, the average of the neighbouring
//   segment slopes s = (q_{i+1} - q_i) / h_i, except v_i = 0 where the slope
//   changes sign or either slope is zero (the point is a turning point, so
//   the joint stops there instead of overshooting it).
//
// Outside [t_0, t_{N-1}] the trajectory holds its first / last point with
// zero velocity and acceleration (Extrapolate::Hold, what a controller
// tracking it sees), or, asked with Extrapolate::Error, throws
// std::invalid_argument naming t and the range. Immutable after construction, hence safe to
// evaluate from several threads.
#pragma once

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

#include "coopsim/checks.hpp"
#include "coopsim/reference.hpp"

namespace coopsim {

enum class KnotVelocities { Given, Heuristic, Spline };

// What evaluating a trajectory outside its time range does: hold the nearest
// end point at rest, or throw std::invalid_argument.
enum class Extrapolate { Hold, Error };
// "hold" or "error"; anything else throws std::invalid_argument naming extrapolate.
Extrapolate extrapolate_from_name(const std::string& name);

class CubicTrajectory : public Reference {
 public:
  using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

  // times: (N,) s, strictly increasing, finite, N >= 2.
  // points: (N, n), row i = joint positions at times[i] (rad or m).
  // velocities: (N, n) (rad/s or m/s). With rule == Given every row is used;
  //   otherwise only the first and last rows (end velocities) are, and the
  //   interior rows are computed. An empty matrix means all zeros.
  // Throws std::invalid_argument naming the argument on bad input.
  CubicTrajectory(std::vector<double> times, RowMat points, RowMat velocities = RowMat(),
                  KnotVelocities rule = KnotVelocities::Heuristic);

  // documentation (Python's too)
  static constexpr char kDoc[] = R"doc(
Piecewise cubic joint trajectory through via-points (the paper's eqs. 6-8).

Segment k of joint j is c0 + c1 tau + c2 tau^2 + c3 tau^3 in the local time
tau = t - times[k], meeting the four Hermite conditions (position and velocity
at both ends), so q and qd are continuous at every knot. Knot velocities:
- qd_points (N, n) if given;
- spline=True: the C2 cubic spline (continuous acceleration) with end
  velocities qd_start, qd_end (default 0);
- otherwise: ends qd_start, qd_end (default 0); interior knots the average of
  the neighbouring segment slopes, or 0 where the slope changes sign or is 0.
Before times[0] and after times[-1] the first / last point is held at rest
(silently, by default: see evaluate's extrapolate).

times: (N,) s, strictly increasing, N >= 2. q_points: (N, n) rad or m
(a flat (N,) array is one joint). qd_points: (N, n) rad/s or m/s.
qd_start, qd_end: (n,). Bad input raises ValueError naming the argument.)doc";
  // From tables as the Python API takes them (kDoc): the knot velocities
  // qd_points (rule Given), or the spline or the heuristic with the end
  // velocities qd_start, qd_end. Throws std::invalid_argument naming the argument.
  static CubicTrajectory from_tables(const Array& times, const Array& q_points, const std::optional<Array>& qd_points,
                                     bool spline, const std::optional<Array>& qd_start,
                                     const std::optional<Array>& qd_end);

  int dof() const override { return n_; }
  double t_start() const override { return times_.front(); }
  double t_end() const override { return times_.back(); }
  void evaluate(double t, double* q, double* qd, double* qdd) const override;
  // Vectorised: m times; q, qd, qdd (each may be null) are row-major (m, n).
  // With Extrapolate::Error a time outside [t_start, t_end] throws
  // std::invalid_argument (naming t and the range) before anything is written.
  void evaluate_many(const double* t, long m, double* q, double* qd, double* qdd,
                     Extrapolate extrapolate = Extrapolate::Hold) const;
  // Throws std::invalid_argument naming t and the range if t is outside [t_start, t_end].
  void check_in_range(double t) const;

  // documentation of evaluate (Python's too)
  static constexpr char kEvaluateDoc[] = R"doc(
(q, qd, qdd) at time t (s): each (n,) for a scalar t, (N, n) for an array of
N times; rad, rad/s, rad/s^2 (m, m/s, m/s^2 for prismatic joints).

Outside [t_start, t_end] the trajectory does not extrapolate its cubics:
extrapolate="hold" (default) silently returns the first / last point with
zero velocity and acceleration (what a controller tracking it is given);
extrapolate="error" raises ValueError naming t and the time range instead.)doc";

  int segments() const { return static_cast<int>(times_.size()) - 1; }
  const std::vector<double>& times() const { return times_; }
  const RowMat& points() const { return points_; }
  const RowMat& velocities() const { return velocities_; }  // knot velocities used (N, n)
  KnotVelocities rule() const { return rule_; }
  // Coefficients [c0, c1, c2, c3] of segment k, joint j, in local time.
  const double* coefficients(int k, int j) const { return &coef_[(static_cast<size_t>(k) * n_ + j) * 4]; }
  // Index k of the segment containing t (clamped to 0..segments()-1).
  int segment(double t) const;

 private:
  void build_();

  std::vector<double> times_;
  RowMat points_;
  RowMat velocities_;
  KnotVelocities rule_;
  int n_ = 0;
  std::vector<double> coef_;  // [segment][joint][4]
};

// Interior knot velocities by the rule above (rows 1..N-2 of v are written;
// rows 0 and N-1 are left as they are).
void heuristic_knot_velocities(const std::vector<double>& t, const CubicTrajectory::RowMat& q,
                               CubicTrajectory::RowMat& v);
// Interior knot velocities of the clamped C^2 cubic spline (rows 0 and N-1 of v
// are the given end velocities), by the tridiagonal (Thomas) algorithm.
void spline_knot_velocities(const std::vector<double>& t, const CubicTrajectory::RowMat& q,
                            CubicTrajectory::RowMat& v);

}  // namespace coopsim
