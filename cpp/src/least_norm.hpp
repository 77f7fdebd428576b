// The least-norm solutions of the object-level law's distribution A x = b (8 rows: the object's force
// and moment, the load share, the squeeze; 6 to 12 columns: each clamp's force and commanded moments),
// used by cooperative_laws.cpp: through the Gram matrix's Cholesky factor when that proves A well
// conditioned, otherwise by the complete orthogonal decomposition. Internal: included by engine
// sources and tests/native/least_norm.cpp, which checks both against Eigen's decomposition.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <limits>

namespace coopsim::least_norm {

// The least-norm solution x = A^T (A A^T)^-1 b of the distribution A x = b (8 rows, 6 to 12 columns) when
// every singular value of A is above 1e-2 of the largest, proved from the Gram matrix G = A A^T's
// Cholesky factor L: sigma_max^2 <= trace(G) and sigma_min^2 >= 1 / ||L^-1||_F^2, so sigma_min / sigma_max >=
// 1 / sqrt(trace(G) ||L^-1||_F^2). Then no direction is near the 1e-3 threshold and the solution is the
// complete orthogonal decomposition's to round-off (the Gram's squared condition, at most 1e4, keeps the
// error near 1e-12), for about a tenth of its instructions. False (x untouched) otherwise: the
// decomposition decides which directions count as zero.
template <class Dist>
inline bool well_conditioned(const Dist& A, const Eigen::Matrix<double, 8, 1>& b,
                                 Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 12, 1>& x) {
  const int cols = static_cast<int>(A.cols());
  double a[8][12];  // A's rows, contiguous
  for (int i = 0; i < 8; ++i)
    for (int k = 0; k < cols; ++k) a[i][k] = A(i, k);
  double L[8][8];  // G's lower factor, row by row
  double trace = 0.0;
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j <= i; ++j) {
      double g = 0.0;
      for (int k = 0; k < cols; ++k) g += a[i][k] * a[j][k];
      if (i == j) trace += g;
      for (int k = 0; k < j; ++k) g -= L[i][k] * L[j][k];
      if (i == j) {
        if (!(g > 0.0)) return false;
        L[i][i] = std::sqrt(g);
      } else {
        L[i][j] = g / L[j][j];
      }
    }
  }
  // ||L^-1||_F^2, column by column of the inverse (lower triangular)
  double inv2 = 0.0;
  for (int c = 0; c < 8; ++c) {
    double y[8];
    for (int i = c; i < 8; ++i) {
      double s = i == c ? 1.0 : 0.0;
      for (int k = c; k < i; ++k) s -= L[i][k] * y[k];
      y[i] = s / L[i][i];
      inv2 += y[i] * y[i];
    }
  }
  if (!(trace * inv2 < 1e4)) return false;
  double y[8];  // G y = b, then x = A^T y
  for (int i = 0; i < 8; ++i) {
    double s = b[i];
    for (int k = 0; k < i; ++k) s -= L[i][k] * y[k];
    y[i] = s / L[i][i];
  }
  for (int i = 7; i >= 0; --i) {
    double s = y[i];
    for (int k = i + 1; k < 8; ++k) s -= L[k][i] * y[k];
    y[i] = s / L[i][i];
  }
  x.resize(cols);
  for (int k = 0; k < cols; ++k) {
    double v = 0.0;
    for (int i = 0; i < 8; ++i) v += a[i][k] * y[i];
    x[k] = v;
  }
  return true;
}

// A Householder reflection H = I - tau [1; v] [1; v]^T that takes the m numbers x[0], x[step], ...,
// x[(m-1) step] to (beta, 0, ..., 0): v written over x's tail, beta over x[0]; Eigen's makeHouseholder.
inline double householder(double* x, int m, int step, double& tau) {
  double tail = 0.0;
  for (int i = 1; i < m; ++i) tail += x[i * step] * x[i * step];
  const double c0 = x[0];
  if (tail <= std::numeric_limits<double>::min()) {
    tau = 0.0;
    for (int i = 1; i < m; ++i) x[i * step] = 0.0;
    return c0;
  }
  double beta = std::sqrt(c0 * c0 + tail);
  if (c0 >= 0.0) beta = -beta;
  for (int i = 1; i < m; ++i) x[i * step] /= c0 - beta;
  tau = (beta - c0) / beta;
  x[0] = beta;
  return beta;
}

// The least-norm solution of the distribution A x = b (8 rows, 6 to 12 columns) by its complete
// orthogonal decomposition, as Eigen's CompleteOrthogonalDecomposition with the given threshold computes
// it (the same steps: a Householder QR with column pivoting by the downdated column norms, the pivots up
// to `threshold` times the largest counted as zero, the trapezoid [R11 R12] reflected from the right to
// [T11 0], Q^T b, T11's back substitution, Z^T and the permutation back), written on fixed arrays: Eigen's
// generic blocks cost some 29 K instructions for the SCARAs' 8 x 9 system, this a few thousand. The
// results agree to round-off (the sums are taken in another order).
template <class Dist>
inline void cod(const Dist& A, const Eigen::Matrix<double, 8, 1>& b, double threshold,
                    Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 12, 1>& x) {
  constexpr int R = 8, kMax = 12;
  const int C = static_cast<int>(A.cols());
  double q[R][kMax];  // A, then its factors (Eigen's layout: R and Q's reflections below the diagonal)
  for (int i = 0; i < R; ++i)
    for (int k = 0; k < C; ++k) q[i][k] = A(i, k);
  double direct[kMax], updated[kMax], hq[R], hz[R];
  int perm[kMax];
  double largest = 0.0;
  for (int k = 0; k < C; ++k) {
    double s = 0.0;
    for (int i = 0; i < R; ++i) s += q[i][k] * q[i][k];
    direct[k] = updated[k] = std::sqrt(s);
    largest = std::max(largest, updated[k]);
    perm[k] = k;
  }
  const double eps = std::numeric_limits<double>::epsilon();
  const double helper = (largest * eps) * (largest * eps) / R, downdate = std::sqrt(eps);
  const int size = std::min(R, C);
  int nonzero = size;
  double maxpivot = 0.0;
  for (int k = 0; k < size; ++k) {
    int big = k;
    for (int j = k + 1; j < C; ++j)
      if (updated[j] > updated[big]) big = j;
    if (nonzero == size && updated[big] * updated[big] < helper * (R - k)) nonzero = k;
    if (big != k) {
      for (int i = 0; i < R; ++i) std::swap(q[i][k], q[i][big]);
      std::swap(updated[k], updated[big]);
      std::swap(direct[k], direct[big]);
      std::swap(perm[k], perm[big]);
    }
    const double beta = householder(&q[k][k], R - k, kMax, hq[k]);
    maxpivot = std::max(maxpivot, std::abs(beta));
    if (hq[k] != 0.0 && R - k > 1) {
      for (int j = k + 1; j < C; ++j) {
        double t = q[k][j];
        for (int i = k + 1; i < R; ++i) t += q[i][k] * q[i][j];
        q[k][j] -= hq[k] * t;
        for (int i = k + 1; i < R; ++i) q[i][j] -= hq[k] * q[i][k] * t;
      }
    }
    for (int j = k + 1; j < C; ++j) {  // the stable norm downdate (LAPACK's xGEQPF)
      if (updated[j] == 0.0) continue;
      double t = std::abs(q[k][j]) / updated[j];
      t = std::max(0.0, (1.0 + t) * (1.0 - t));
      const double ratio = updated[j] / direct[j];
      if (t * ratio * ratio <= downdate) {
        double s = 0.0;
        for (int i = k + 1; i < R; ++i) s += q[i][j] * q[i][j];
        direct[j] = updated[j] = std::sqrt(s);
      } else {
        updated[j] *= std::sqrt(t);
      }
    }
  }
  int rank = 0;
  for (int i = 0; i < nonzero; ++i) rank += std::abs(q[i][i]) > maxpivot * threshold;
  // [R11 R12] = [T11 0] Z, row by row from the last: Z(k) zeroes row k's part beyond the rank
  if (rank < C) {
    for (int k = rank - 1; k >= 0; --k) {
      if (k != rank - 1)
        for (int i = 0; i <= k; ++i) std::swap(q[i][k], q[i][rank - 1]);
      householder(&q[k][rank - 1], C - rank + 1, 1, hz[k]);
      if (k > 0 && hz[k] != 0.0 && C - rank + 1 > 1) {
        for (int i = 0; i < k; ++i) {
          double t = q[i][rank - 1];
          for (int j = rank; j < C; ++j) t += q[i][j] * q[k][j];
          q[i][rank - 1] -= hz[k] * t;
          for (int j = rank; j < C; ++j) q[i][j] -= hz[k] * t * q[k][j];
        }
      }
      if (k != rank - 1)
        for (int i = 0; i <= k; ++i) std::swap(q[i][k], q[i][rank - 1]);
    }
  }
  x.setZero(C);
  if (rank == 0) return;
  double c[R];  // Q^T b
  for (int i = 0; i < R; ++i) c[i] = b[i];
  for (int k = 0; k < rank; ++k) {
    if (hq[k] == 0.0 || R - k == 1) continue;
    double t = c[k];
    for (int i = k + 1; i < R; ++i) t += q[i][k] * c[i];
    c[k] -= hq[k] * t;
    for (int i = k + 1; i < R; ++i) c[i] -= hq[k] * q[i][k] * t;
  }
  double y[kMax];
  for (int i = rank - 1; i >= 0; --i) {
    double s = c[i];
    for (int j = i + 1; j < rank; ++j) s -= q[i][j] * y[j];
    y[i] = s / q[i][i];
  }
  for (int i = rank; i < C; ++i) y[i] = 0.0;
  if (rank < C) {  // y = Z^T [z; 0]
    for (int k = 0; k < rank; ++k) {
      if (k != rank - 1) std::swap(y[k], y[rank - 1]);
      if (hz[k] != 0.0 && C - rank + 1 > 1) {
        double t = y[rank - 1];
        for (int j = rank; j < C; ++j) t += q[k][j] * y[j];
        y[rank - 1] -= hz[k] * t;
        for (int j = rank; j < C; ++j) y[j] -= hz[k] * q[k][j] * t;
      }
      if (k != rank - 1) std::swap(y[k], y[rank - 1]);
    }
  }
  for (int i = 0; i < C; ++i) x[perm[i]] = y[i];
}

}  // namespace coopsim::least_norm
