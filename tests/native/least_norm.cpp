// The object-level law's least-norm solvers (cpp/src/least_norm.hpp) against Eigen's
// CompleteOrthogonalDecomposition with the same threshold (1e-3), on 28,000 seeded random systems of
// 8 rows and 6 to 12 columns: full rank, rank-deficient (a row a combination of two others),
// nearly so (the same, perturbed by 1e-6 of a third row: below the threshold, counted as deficient), a
// zero column beside one a thousand times larger. Each solution must equal Eigen's to 1e-10 of its
// norm, and the rank must be the same (what the threshold decides). The Gram path, where it accepts a
// system, must give the decomposition's solution to 1e-9 of its norm, and it must accept every
// well-conditioned full-rank system of the sample. Exit status 0 when all hold (scripts/test_threads.sh
// runs it).
#include <Eigen/QR>

#include <cstdio>
#include <random>

#include "least_norm.hpp"

int main() {
  using Dist = Eigen::Matrix<double, 8, Eigen::Dynamic, 0, 8, 12>;
  using X = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 12, 1>;
  std::mt19937 gen(1);
  std::normal_distribution<double> normal(0.0, 1.0);
  double worst_cod = 0.0, worst_gram = 0.0;
  int failures = 0, gram_used = 0, gram_refused_full = 0;
  for (int trial = 0; trial < 28000; ++trial) {
    const int cols = 6 + trial % 7, kind = (trial / 7) % 4;
    Dist A(8, cols);
    for (int i = 0; i < 8; ++i)
      for (int k = 0; k < cols; ++k) A(i, k) = normal(gen);
    if (kind == 1) A.row(7) = 0.3 * A.row(1) - 2.0 * A.row(4);
    if (kind == 2) A.row(7) = 0.3 * A.row(1) - 2.0 * A.row(4) + 1e-6 * A.row(0);
    if (kind == 3) {
      A.col(0).setZero();
      A.col(cols - 1) *= 1e3;
    }
    Eigen::Matrix<double, 8, 1> b;
    for (int i = 0; i < 8; ++i) b[i] = normal(gen);
    Eigen::CompleteOrthogonalDecomposition<Dist> eig(8, cols);
    eig.setThreshold(1e-3);
    eig.compute(A);
    const X want = eig.solve(b);
    X got;
    coopsim::least_norm::cod(A, b, 1e-3, got);
    const double scale = std::max(want.norm(), 1e-300);
    const double d = (got - want).norm() / scale;
    worst_cod = std::max(worst_cod, d);
    if (!(d <= 1e-10) || got.size() != cols) {
      if (++failures <= 5) std::printf("cod: trial %d (kind %d, %d columns, rank %ld): %.3g\n", trial, kind, cols,
                                       static_cast<long>(eig.rank()), d);
    }
    X gram;
    if (coopsim::least_norm::well_conditioned(A, b, gram)) {
      ++gram_used;
      const double g = (gram - want).norm() / scale;
      worst_gram = std::max(worst_gram, g);
      if (!(g <= 1e-9) || eig.rank() != 8) {
        if (++failures <= 5) std::printf("gram: trial %d (kind %d, %d columns): %.3g\n", trial, kind, cols, g);
      }
    } else if (kind == 0 && cols >= 10) {
      // a random 8 x 10..12 Gaussian matrix is well conditioned (sigma_min / sigma_max > 1e-2) nearly always
      ++gram_refused_full;
    }
  }
  std::printf("least_norm: cod against Eigen's, worst %.3g; Gram path used %d times, worst %.3g; refused %d "
              "well-shaped full-rank systems; %d failures\n", worst_cod, gram_used, worst_gram, gram_refused_full,
              failures);
  if (gram_used < 1000 || gram_refused_full > 100) {
    std::printf("least_norm: the Gram path accepted too few systems\n");
    return 1;
  }
  return failures == 0 ? 0 : 1;
}
