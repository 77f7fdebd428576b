// The log: its schema, its columns' storage (a bounded pool of memory blocks), the tracking
// metrics, and the log stage of a simulation's step (the row at t_k).
#include "coopsim/log.hpp"
#include "coopsim/simulation.hpp"
#include "stages.hpp"

#include <map>
#include <mutex>
#include <new>

#include <unistd.h>

namespace coopsim {

const std::array<LogQuantityInfo, kLogQuantities>& log_schema() {
  static const std::array<LogQuantityInfo, kLogQuantities> schema = {{
      {"q", "joint positions at t (rad or m)"},
      {"qd", "joint velocities at t (rad/s or m/s)"},
      {"qdd", "joint accelerations at t under the held torques (rad/s^2 or m/s^2)"},
      {"tau", "torque applied over [t, t + dt), held and saturated (N m or N)"},
      {"tau_ext", "joint torque of the applied forces and wrenches over [t, t + dt), held (N m or N)"},
      {"q_ref", "reference positions at t (rad or m)"},
      {"qd_ref", "reference velocities at t (rad/s or m/s)"},
      {"qdd_ref", "reference accelerations at t (rad/s^2 or m/s^2)"},
  }};
  return schema;
}

VecN TrackingMetrics::rms_error() const {
  if (steps == 0) return VecN::Zero(sum_sq_error.size());
  return (sum_sq_error / static_cast<double>(steps)).cwiseSqrt();
}

namespace {

// Log blocks freed lately, kept for the next logs: writing fresh memory costs
// a page fault per page (dear under virtualisation), reusing it does not.
// Bounded; leaked on purpose so that blocks freed at exit find it alive.
class BlockPool {
 public:
  static BlockPool& get() {
    static BlockPool* pool = new BlockPool;
    return *pool;
  }
  // A block of at least n doubles (its size in *size), reused when one of
  // at most 2 n is free.
  std::shared_ptr<double[]> take(size_t n, size_t* size) {
    double* p = nullptr;
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto it = free_.lower_bound(n);
      if (it != free_.end() && it->first <= 2 * n) {
        p = it->second;
        *size = it->first;
        bytes_ -= it->first * sizeof(double);
        free_.erase(it);
      }
    }
    if (!p) {
      p = new double[n];  // uninitialised: pages are touched when rows are written
      *size = n;
    }
    const size_t sz = *size;
    return std::shared_ptr<double[]>(p, [sz](double* q) { BlockPool::get().give(q, sz); });
  }
  void give(double* p, size_t n) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (bytes_ + n * sizeof(double) <= kMaxBytes) {
        free_.emplace(n, p);
        bytes_ += n * sizeof(double);
        return;
      }
    }
    delete[] p;
  }

 private:
  static constexpr size_t kMaxBytes = size_t(64) << 20;
  std::mutex mu_;
  std::multimap<size_t, double*> free_;
  size_t bytes_ = 0;
};

// The machine's memory, bytes (physical pages; 1 TiB where the system does not say).
size_t memory_bytes() {
  static const size_t bytes = [] {
    const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? static_cast<size_t>(pages) * static_cast<size_t>(page) : size_t(1) << 40;
  }();
  return bytes;
}

}  // namespace

void LogColumn::reserve(long rows) {
  if (rows <= cap_) return;
  // a log larger than the machine's memory is refused as new[] refuses what it cannot give
  // (std::bad_alloc), before asking: the size in bytes could overflow, and an allocator may
  // abort rather than throw (AddressSanitizer's does on requests beyond its limit)
  const long limit = static_cast<long>(memory_bytes() / sizeof(double) / static_cast<size_t>(width_));
  if (rows > limit) throw std::bad_alloc();
  const long want = std::min(std::max(rows, 2 * cap_), limit);
  size_t size = 0;
  std::shared_ptr<double[]> b = BlockPool::get().take(static_cast<size_t>(want) * width_, &size);
  if (rows_) std::copy(block_.get(), block_.get() + rows_ * width_, b.get());
  block_ = std::move(b);
  cap_ = static_cast<long>(size / width_);
}

namespace stages {

void reserve(const Model& m, Data& d, long steps) {
  if (m.options.log_every == 0 || steps <= 0) return;
  const long rows = d.log_t.rows() + steps / m.options.log_every + 2;
  d.log_t.reserve(rows);
  for (RobotData& s : d.robots) {
    for (LogColumn& c : s.record.log.columns) c.reserve(rows);
    s.record.log.grasp.reserve(rows);
    s.record.log.ft.reserve(rows);
  }
  for (LogColumn& c : d.body_log) c.reserve(rows);
  for (PairData& p : d.pairs) p.log.reserve(rows);
}

namespace {

void log_pairs(const Model& m, Data& d) {
  double row[kCooperationWidth];
  Cooperation c;
  for (PairData& p : d.pairs) {
    const bool both = cooperation(m, d, p, c);
    cooperation_row(both ? d.robots[p.a].grasp.held : -1, both ? &c : nullptr, row);
    p.log.push(row);
  }
}

}  // namespace

// The log stage: at every log_every-th step, the row at t_k (once per time, unless the applied
// inputs changed since). The acceleration logged is the first stage of the next integration.
void log(const Model& m, Data& d) {
  if (m.options.log_every == 0 || d.k % m.options.log_every != 0 || d.logged_at == d.k) return;
  for (size_t i = 0; i < d.robots.size(); ++i) {
    RobotData& s = d.robots[i];
    try {
      qdd(m, d, static_cast<int>(i), s.state.k1);
    } catch (const std::exception& e) {
      diverge(m, d, static_cast<int>(i), e.what(), false, true);
    }
    s.state.k1_valid = true;
  }
  const double now = d.time(m);
  d.log_t.push(&now);
  for (RobotData& s : d.robots) {
    auto& c = s.record.log.columns;
    c[kLogQ].push(s.state.q.data());
    c[kLogQd].push(s.state.qd.data());
    c[kLogQdd].push(s.state.k1.data());
    c[kLogTau].push(s.control.tau.data());
    c[kLogTauExt].push(s.external.tau.data());
    c[kLogQRef].push(s.control.q_ref.data());
    c[kLogQdRef].push(s.control.qd_ref.data());
    c[kLogQddRef].push(s.control.qdd_ref.data());
    const Vec6& weld = s.grasp.weld;
    double g[7] = {static_cast<double>(s.grasp.held), weld[0], weld[1], weld[2], weld[3], weld[4], weld[5]};
    s.record.log.grasp.push(g);
    double ft[12];
    Eigen::Map<Vec6>(ft + 0) = s.sensor.world;
    Eigen::Map<Vec6>(ft + 6) = s.sensor.clamp;
    s.record.log.ft.push(ft);
  }
  for (size_t b = 0; b < d.body_log.size(); ++b) {
    const BodyState& st = d.body_now[b];
    const Eigen::Quaterniond quat(st.pose.linear());
    double row[13];
    Eigen::Map<Eigen::Vector3d>(row + 0) = st.pose.translation();
    row[3] = quat.w();
    row[4] = quat.x();
    row[5] = quat.y();
    row[6] = quat.z();
    Eigen::Map<Eigen::Vector3d>(row + 7) = st.velocity;
    Eigen::Map<Eigen::Vector3d>(row + 10) = st.angular_velocity;
    d.body_log[b].push(row);
  }
  log_pairs(m, d);
  d.logged_at = d.k;
}

}  // namespace stages

void Simulation::reserve(long steps) {
  const Entry driving = enter_();  // one driver at a time
  stages::reserve(*model_, data_, steps);
}

}  // namespace coopsim
