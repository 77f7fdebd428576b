// Helpers the simulation's sources share (simulation.cpp and the files of its stages); internal.
#pragma once

#include <chrono>
#include <sstream>
#include <string>

#include "coopsim/robot.hpp"

namespace coopsim::detail {

// A vector as the simulation's messages show it: [a, b, ...], six significant digits.
inline std::string vec_str(const VecN& v) {
  std::ostringstream s;
  s.precision(6);
  s << "[";
  for (int i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
  s << "]";
  return s.str();
}

// Adds the seconds of its scope to `total` when `on` (the simulation's profiler); free when off.
class Stopwatch {
 public:
  using clock = std::chrono::steady_clock;
  Stopwatch(bool on, double& total) : total_(on ? &total : nullptr), t0_(on ? clock::now() : clock::time_point()) {}
  ~Stopwatch() {
    if (total_) *total_ += std::chrono::duration<double>(clock::now() - t0_).count();
  }
  Stopwatch(const Stopwatch&) = delete;
  Stopwatch& operator=(const Stopwatch&) = delete;

 private:
  double* total_;
  clock::time_point t0_;
};

}  // namespace coopsim::detail
