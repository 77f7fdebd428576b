// A simulation's log storage and its tracking metrics. The log is a set of append-only columns;
// their memory blocks come from a bounded process-wide pool (cpp/src/log.cpp). What a simulation
// writes into them, and when, is described in simulation.hpp.
#pragma once

#include <algorithm>
#include <array>
#include <memory>

#include "coopsim/robot.hpp"

namespace coopsim {

// Append-only rows of `width` doubles, row-major in one memory block.
// Growing moves the rows to a new block and clear() starts a new one, so
// rows already written never change in a block: whoever shares a block
// (e.g. a numpy view) sees a fixed history. Blocks come from, and go back
// to, a bounded process-wide pool, so that repeated runs reuse memory whose
// pages are already mapped.
class LogColumn {
 public:
  explicit LogColumn(int width = 1) : width_(width) {}
  int width() const { return width_; }
  long rows() const { return rows_; }
  long capacity() const { return cap_; }
  const std::shared_ptr<double[]>& block() const { return block_; }
  const double* data() const { return block_.get(); }
  double back() const { return block_[(rows_ - 1) * width_ + width_ - 1]; }
  // Room for `rows` rows in all; grows at least geometrically. Throws std::bad_alloc beyond the
  // machine's memory.
  void reserve(long rows);
  // Appends one row (reserve first to keep allocation out of loops).
  void push(const double* row) {
    if (rows_ == cap_) reserve(rows_ + 1);
    std::copy(row, row + width_, block_.get() + rows_ * width_);
    ++rows_;
  }
  void clear() {
    block_.reset();
    rows_ = cap_ = 0;
  }

 private:
  std::shared_ptr<double[]> block_;
  long rows_ = 0, cap_ = 0;
  int width_ = 1;
};

// The log's schema: the quantities logged per robot, in column order, each
// one column per joint. Units per joint type: rad or m, rad/s or m/s,
// rad/s^2 or m/s^2, N m or N.
enum LogQuantity : int {
  kLogQ,
  kLogQd,
  kLogQdd,
  kLogTau,
  kLogTauExt,
  kLogQRef,
  kLogQdRef,
  kLogQddRef,
  kLogQuantities
};
struct LogQuantityInfo {
  const char* name;  // column prefix, e.g. "tau_ext"
  const char* doc;   // what a row holds
};
const std::array<LogQuantityInfo, kLogQuantities>& log_schema();

// One robot's log: one (rows x n) column per quantity of log_schema().
struct RobotLog {
  std::array<LogColumn, kLogQuantities> columns;
  // per row: the world id of the body held (-1: none), then the weld's force
  // (N) and moment (N m) on it over the world step, world frame (7 values)
  LogColumn grasp{7};
  // per row: the force/torque sensor's reading (SensorOptions, simulation.hpp), force (N) and moment
  // (N m) about the tool centre point that the robot's end applies to its environment: world axes (6),
  // then the sensor frame (6)
  LogColumn ft{12};
  const LogColumn& operator[](int quantity) const { return columns[quantity]; }
};

// A robot's tracking metrics over every step (whatever log_every): per joint, of e = q_ref - q and tau.
struct TrackingMetrics {
  long steps = 0;      // samples counted
  VecN sum_sq_error;   // sum of e_i^2
  VecN max_abs_error;  // max |e_i|
  VecN max_abs_tau;    // max |tau_i| applied
  // Root-mean-square tracking error per joint over the samples (zeros before any).
  VecN rms_error() const;
};

}  // namespace coopsim
