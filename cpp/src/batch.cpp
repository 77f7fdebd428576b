// run_batch: independent simulations advanced on a pool of threads.
#include "coopsim/batch.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>

namespace coopsim {

std::vector<std::exception_ptr> run_batch(const std::vector<Simulation*>& sims, double t_end, int threads,
                                          std::vector<double>* seconds) {
  const int N = static_cast<int>(sims.size());
  for (int i = 0; i < N; ++i) {
    if (!sims[i]) throw std::invalid_argument("sims must not contain None");
    for (int j = 0; j < i; ++j) {
      if (sims[i] == sims[j])
        throw std::invalid_argument("sims[" + std::to_string(i) + "] is the same simulation as sims[" +
                                    std::to_string(j) + "]");
      for (int a = 0; a < sims[i]->robot_count(); ++a)
        for (int b = 0; b < sims[j]->robot_count(); ++b)
          if (sims[i]->controller(a) == sims[j]->controller(b))
            throw std::invalid_argument("sims[" + std::to_string(i) + "] and sims[" + std::to_string(j) +
                                        "] share a controller instance: give each its own");
    }
  }
  if (!std::isfinite(t_end)) throw std::invalid_argument("t_end must be finite");
  std::vector<std::exception_ptr> errors(N);
  if (seconds) seconds->assign(N, 0.0);
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::max(1, std::min(threads, N));
  // Balanced: each thread takes the next simulation from one atomic counter when it is idle (a long run or a
  // preempted thread does not hold the others back), the calling thread one of them. A run writes its own
  // data only (its model is read-only, shared between runs of one model); the batch's outputs, errors[i] and
  // seconds[i], are written once per simulation, never in the stepping loop, and the log's storage is
  // reserved before each advance (Simulation::advance), so nothing is allocated per step.
  std::atomic<int> next{0};
  auto work = [&]() {
    for (int i = next++; i < N; i = next++) {
      const auto start = std::chrono::steady_clock::now();
      try {
        sims[i]->advance(sims[i]->steps_until(t_end));
      } catch (...) {
        errors[i] = std::current_exception();
      }
      if (seconds) (*seconds)[i] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& th : pool) th.join();
  return errors;
}

}  // namespace coopsim
