// The batches' pool (forward_dynamics_batch, forward_dynamics_derivatives_batch): items 0 .. N-1 in chunks
// of consecutive items, taken by whichever thread is idle from one atomic counter (a slow core or a
// preempted thread does not hold the others back), the calling thread one of the pool. Each thread makes
// its own state once (workspaces, outputs) and writes only its items' rows: nothing is allocated per item.
// The first failing item, as a serial loop would report it, is rethrown with its row named (std::domain_error
// and std::invalid_argument keep their type). Internal: engine sources only.
#pragma once

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace coopsim::detail {

// make() -> a thread's state; item(state, i) does item i. threads <= 0: every core.
template <class Make, class Item>
void batch_rows(int N, int chunk, int threads, Make make, Item item) {
  if (N <= 0) return;
  const int chunks = (N + chunk - 1) / chunk;
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::max(1, std::min(threads, chunks));
  std::atomic<int> next{0};
  std::atomic<bool> failed{false};
  std::mutex error_mutex;
  int error_row = N;
  std::exception_ptr error;
  auto work = [&]() {
    auto state = make();
    for (int c = next++; c < chunks && !failed.load(std::memory_order_relaxed); c = next++) {
      const int end = std::min(N, (c + 1) * chunk);
      for (int i = c * chunk; i < end; ++i) {
        try {
          item(state, i);
        } catch (...) {
          // every chunk before this one was taken before it and runs to its own end or its own first failure
          std::lock_guard<std::mutex> lock(error_mutex);
          if (i < error_row) {
            error_row = i;
            error = std::current_exception();
          }
          failed = true;
          break;
        }
      }
    }
  };
  if (threads == 1) {
    work();
  } else {
    std::vector<std::thread> pool;
    pool.reserve(threads - 1);
    for (int t = 1; t < threads; ++t) pool.emplace_back(work);
    work();  // the calling thread is one of the pool
    for (auto& th : pool) th.join();
  }
  if (error) {
    const std::string row = "state " + std::to_string(error_row) + " (row of q, qd, tau): ";
    try {
      std::rethrow_exception(error);
    } catch (const std::domain_error& e) {
      throw std::domain_error(row + e.what());
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(row + e.what());
    }
  }
}

}  // namespace coopsim::detail
