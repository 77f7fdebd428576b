// Simulations run side by side on threads (run_batch, cpp/src/batch.cpp).
#pragma once

#include <condition_variable>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "coopsim/simulation.hpp"

namespace coopsim {

// Runs each simulation up to time t_end on a pool of `threads` threads
// (0: hardware concurrency; the calling thread is one of them), each taking
// the next simulation when idle. Simulations must be distinct and must not share
// controller instances. Returns one exception per simulation (null when it
// finished), so that one failed run does not stop the others; `seconds`, when
// given, receives each run's wall time (s). Throws std::invalid_argument on a
// null or repeated simulation, a shared controller or a non-finite t_end.
std::vector<std::exception_ptr> run_batch(const std::vector<Simulation*>& sims, double t_end, int threads,
                                          std::vector<double>* seconds = nullptr);

// A pool of engine threads that advance chunks of simulations handed to it one at a time, in the order
// given, each idle thread taking the next: the vector environments' pipeline (coopsim.envs.vector), where
// the caller's thread prepares the next chunk (Python) while the pool advances and reads the last ones.
// Its threads never take the GIL.
class AdvancePool {
 public:
  // What one submit() did, filled by a pool thread; wait() blocks until it is done.
  struct Job {
    std::vector<std::exception_ptr> errors;  // per simulation, as run_batch's
    std::vector<double> seconds;             // per simulation, its run's wall time (s)
    Simulation::ReadoutRows rows;            // pair_readout's rows, when asked
    std::exception_ptr failure;              // run_batch's or pair_readout's own exception (bad arguments)
    void wait();
    bool done();  // whether it is done, without waiting

   private:
    friend class AdvancePool;
    std::vector<Simulation*> sims_;
    std::vector<double> t_end_;
    int a_ = 0, b_ = 0;
    std::string body_;
    bool done_ = false;
    std::mutex m_;
    std::condition_variable cv_;
  };
  // `threads` >= 1 engine threads, started now and joined by the destructor (after the jobs queued).
  explicit AdvancePool(int threads);
  ~AdvancePool();
  AdvancePool(const AdvancePool&) = delete;
  AdvancePool& operator=(const AdvancePool&) = delete;
  // Queues: advance each sims[i] to t_end[i] (those of one end time in one run_batch call on the pool
  // thread, run_batch's checks), then, when `body` is not empty, Simulation::pair_readout(sims, a, b, body).
  // The simulations must stay alive until the job is done; one in two jobs at once is refused to the
  // second (its error a SimulationBusyError: one driver at a time), so a chunk that follows another with
  // the same simulations waits for that one's result first.
  std::shared_ptr<Job> submit(std::vector<Simulation*> sims, std::vector<double> t_end, int a = 0, int b = 0,
                              std::string body = {});
  // Runs the job queued first on the calling thread, as a pool thread would (the caller helping its pool
  // instead of waiting: a pipeline whose caller has nothing else to do); false when none is queued.
  bool run_one();
  int threads() const { return static_cast<int>(threads_.size()); }

 private:
  void work();
  static void run(Job& job);
  std::vector<std::thread> threads_;
  std::deque<std::shared_ptr<Job>> queue_;
  std::mutex m_;
  std::condition_variable cv_;
  bool stop_ = false;
};

}  // namespace coopsim
