#include "coopsim/trajectory.hpp"

#include "internal.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace coopsim {

namespace {

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

using RowMat = CubicTrajectory::RowMat;

// a table of one row per time (N rows; n columns, -1: any; a flat (N,) array is one joint)
RowMat per_time(const Array& a, std::ptrdiff_t N, std::ptrdiff_t n, const char* name) {
  const bool flat = a.ndim() == 1 && n <= 1;
  if (!flat && a.ndim() != 2)
    fail(std::string("wrong shape for ") + name + ": expected (N, n), got " + shape_string(a.shape.data(), a.ndim()));
  if (a.shape[0] != N)
    fail(std::string("wrong length for ") + name + ": expected " + std::to_string(N) + " rows (one per time), got " +
         std::to_string(a.shape[0]));
  if (!flat) check_shape(a, {N, n}, name);
  check_finite(a, name);
  return Eigen::Map<const RowMat>(a.values.data(), N, flat ? 1 : a.shape[1]);
}

}  // namespace

CubicTrajectory CubicTrajectory::from_tables(const Array& times, const Array& q_points,
                                             const std::optional<Array>& qd_points, bool spline,
                                             const std::optional<Array>& qd_start,
                                             const std::optional<Array>& qd_end) {
  check_shape(times, {-1}, "times");
  const std::ptrdiff_t N = times.shape[0];
  if (N < 2) fail("times must have at least 2 points (one segment), got " + std::to_string(N));
  check_finite(times, "times");
  RowMat Q = per_time(q_points, N, -1, "q_points");
  const std::ptrdiff_t n = Q.cols();
  if (qd_points) {
    if (spline)
      fail("qd_points cannot be given with spline=True (the spline sets the interior velocities); give qd_start "
           "and qd_end instead");
    if (qd_start || qd_end)
      fail("qd_start / qd_end cannot be given with qd_points (its first and last rows are the end velocities)");
    return CubicTrajectory(times.values, std::move(Q), per_time(*qd_points, N, n, "qd_points"), KnotVelocities::Given);
  }
  RowMat V = RowMat::Zero(N, n);
  const std::optional<Array>* ends[2] = {&qd_start, &qd_end};
  const char* names[2] = {"qd_start", "qd_end"};
  for (int e = 0; e < 2; ++e)
    if (*ends[e]) {
      check_shape(**ends[e], {n}, names[e]);
      check_finite(**ends[e], names[e]);
      V.row(e ? N - 1 : 0) = Eigen::Map<const Eigen::RowVectorXd>((*ends[e])->values.data(), n);
    }
  return CubicTrajectory(times.values, std::move(Q), std::move(V),
                         spline ? KnotVelocities::Spline : KnotVelocities::Heuristic);
}

CubicTrajectory::CubicTrajectory(std::vector<double> times, RowMat points, RowMat velocities,
                                 KnotVelocities rule)
    : times_(std::move(times)), points_(std::move(points)), velocities_(std::move(velocities)), rule_(rule) {
  const long N = static_cast<long>(times_.size());
  if (N < 2) fail("times must have at least 2 points (one segment), got " + std::to_string(N));
  for (long i = 0; i < N; ++i)
    if (!std::isfinite(times_[i])) fail("times must be finite (got NaN or inf at index " + std::to_string(i) + ")");
  for (long i = 0; i + 1 < N; ++i)
    if (!(times_[i + 1] > times_[i])) {
      std::ostringstream s;
      s << "times must be strictly increasing: times[" << i + 1 << "] = " << times_[i + 1] << " <= times[" << i
        << "] = " << times_[i];
      fail(s.str());
    }
  if (points_.rows() != N)
    fail("q_points must have one row per time: expected " + std::to_string(N) + " rows, got " +
         std::to_string(points_.rows()));
  n_ = static_cast<int>(points_.cols());
  if (n_ < 1) fail("q_points must have at least one joint column");
  if (!points_.allFinite()) fail("q_points must be finite (got NaN or inf)");
  if (velocities_.size() == 0) {
    if (rule_ == KnotVelocities::Given) fail("qd_points must be given when the knot velocity rule is 'given'");
    velocities_ = RowMat::Zero(N, n_);
  }
  if (velocities_.rows() != N || velocities_.cols() != n_) {
    std::ostringstream s;
    s << "wrong shape for qd_points: expected (" << N << ", " << n_ << "), got (" << velocities_.rows() << ", "
      << velocities_.cols() << ")";
    fail(s.str());
  }
  if (!velocities_.allFinite()) fail("qd_points must be finite (got NaN or inf)");
  if (rule_ == KnotVelocities::Heuristic) heuristic_knot_velocities(times_, points_, velocities_);
  if (rule_ == KnotVelocities::Spline) spline_knot_velocities(times_, points_, velocities_);
  build_();
}

void heuristic_knot_velocities(const std::vector<double>& t, const CubicTrajectory::RowMat& q,
                               CubicTrajectory::RowMat& v) {
  const long N = q.rows();
  for (long i = 1; i + 1 < N; ++i) {
    const double h0 = t[i] - t[i - 1], h1 = t[i + 1] - t[i];
    for (long j = 0; j < q.cols(); ++j) {
      const double s0 = (q(i, j) - q(i - 1, j)) / h0, s1 = (q(i + 1, j) - q(i, j)) / h1;
      // a turning point (or a flat neighbour): stop there rather than overshoot
      v(i, j) = (s0 * s1 > 0.0) ? 0.5 * (s0 + s1) : 0.0;
    }
  }
}

void spline_knot_velocities(const std::vector<double>& t, const CubicTrajectory::RowMat& q,
                            CubicTrajectory::RowMat& v) {
  const long N = q.rows();
  const long m = N - 2;  // unknowns v_1 .. v_{N-2}
  if (m <= 0) return;
  // continuity of acceleration at knot i:
  //   h_i v_{i-1} + 2 (h_{i-1} + h_i) v_i + h_{i-1} v_{i+1} = 3 (h_i s_{i-1} + h_{i-1} s_i)
  // strictly diagonally dominant, so the Thomas algorithm is stable
  std::vector<double> a(m), b(m), c(m), d(m);
  for (long j = 0; j < q.cols(); ++j) {
    for (long k = 0; k < m; ++k) {
      const long i = k + 1;
      const double h0 = t[i] - t[i - 1], h1 = t[i + 1] - t[i];
      const double s0 = (q(i, j) - q(i - 1, j)) / h0, s1 = (q(i + 1, j) - q(i, j)) / h1;
      a[k] = h1;
      b[k] = 2.0 * (h0 + h1);
      c[k] = h0;
      d[k] = 3.0 * (h1 * s0 + h0 * s1);
    }
    d[0] -= a[0] * v(0, j);
    d[m - 1] -= c[m - 1] * v(N - 1, j);
    for (long k = 1; k < m; ++k) {
      const double w = a[k] / b[k - 1];
      b[k] -= w * c[k - 1];
      d[k] -= w * d[k - 1];
    }
    v(m, j) = d[m - 1] / b[m - 1];
    for (long k = m - 2; k >= 0; --k) v(k + 1, j) = (d[k] - c[k] * v(k + 2, j)) / b[k];
  }
}

void CubicTrajectory::build_() {
  const int S = segments();
  coef_.assign(static_cast<size_t>(S) * n_ * 4, 0.0);
  for (int k = 0; k < S; ++k) {
    const double h = times_[k + 1] - times_[k];
    for (int j = 0; j < n_; ++j) {
      const double q0 = points_(k, j), q1 = points_(k + 1, j);
      const double v0 = velocities_(k, j), v1 = velocities_(k + 1, j);
      const double s = (q1 - q0) / h;
      double* c = &coef_[(static_cast<size_t>(k) * n_ + j) * 4];
      // closed-form solution of the 4x4 Hermite system in local time
      c[0] = q0;
      c[1] = v0;
      c[2] = (3.0 * s - 2.0 * v0 - v1) / h;
      c[3] = (v0 + v1 - 2.0 * s) / (h * h);
      // bounds of |q|, |qd|, |qdd| over the segment: finite bounds mean no
      // evaluation can overflow into inf or NaN
      const double a0 = std::abs(c[0]), a1 = std::abs(c[1]) * h, a2 = std::abs(c[2]) * h * h,
                   a3 = std::abs(c[3]) * h * h * h;
      const double bound = std::max({a0 + a1 + a2 + a3, (a1 + 2 * a2 + 3 * a3) / h, (2 * a2 + 6 * a3) / (h * h)});
      if (!(bound < 1e300)) {
        std::ostringstream msg;
        msg << "segment " << k << " of joint " << j << " (t = " << times_[k] << " .. " << times_[k + 1]
            << " s) overflows: its positions, velocities or accelerations exceed 1e300 (q_points, qd_points "
               "or time steps out of range)";
        fail(msg.str());
      }
    }
  }
}

int CubicTrajectory::segment(double t) const {
  const int S = segments();
  // first knot strictly after t, minus one; the last knot belongs to the last segment
  const auto it = std::upper_bound(times_.begin(), times_.end(), t);
  int k = static_cast<int>(it - times_.begin()) - 1;
  return std::clamp(k, 0, S - 1);
}

void CubicTrajectory::evaluate(double t, double* q, double* qd, double* qdd) const {
  const long last = static_cast<long>(times_.size()) - 1;
  if (t < times_.front() || t > times_.back()) {
    // hold the nearest end point at rest
    const long row = t < times_.front() ? 0 : last;
    for (int j = 0; j < n_; ++j) {
      if (q) q[j] = points_(row, j);
      if (qd) qd[j] = 0.0;
      if (qdd) qdd[j] = 0.0;
    }
    return;
  }
  const int k = segment(t);
  const double tau = t - times_[k];
  const double* c = &coef_[static_cast<size_t>(k) * n_ * 4];
  for (int j = 0; j < n_; ++j, c += 4) {
    if (q) q[j] = c[0] + tau * (c[1] + tau * (c[2] + tau * c[3]));
    if (qd) qd[j] = c[1] + tau * (2.0 * c[2] + tau * 3.0 * c[3]);
    if (qdd) qdd[j] = 2.0 * c[2] + 6.0 * c[3] * tau;
  }
}

Extrapolate extrapolate_from_name(const std::string& name) {
  if (name == "hold") return Extrapolate::Hold;
  if (name == "error") return Extrapolate::Error;
  fail("extrapolate must be 'hold' or 'error', got '" + name + "'");
}

void CubicTrajectory::check_in_range(double t) const {
  if (t >= times_.front() && t <= times_.back()) return;
  fail("t = " + detail::num(t) + " s is outside the trajectory's time range [" + detail::num(times_.front()) + ", " +
       detail::num(times_.back()) + "] s (extrapolate='error'; extrapolate='hold' holds the end point)");
}

void CubicTrajectory::evaluate_many(const double* t, long m, double* q, double* qd, double* qdd,
                                    Extrapolate extrapolate) const {
  if (extrapolate == Extrapolate::Error)
    for (long i = 0; i < m; ++i) check_in_range(t[i]);
  for (long i = 0; i < m; ++i)
    evaluate(t[i], q ? q + i * n_ : nullptr, qd ? qd + i * n_ : nullptr, qdd ? qdd + i * n_ : nullptr);
}

}  // namespace coopsim
