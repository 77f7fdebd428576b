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

void AdvancePool::Job::wait() {
  std::unique_lock<std::mutex> lock(m_);
  cv_.wait(lock, [this] { return done_; });
}

bool AdvancePool::Job::done() {
  std::lock_guard<std::mutex> lock(m_);
  return done_;
}

AdvancePool::AdvancePool(int threads) {
  if (threads < 1 || threads > 4096)
    throw std::invalid_argument("threads must be 1 to 4096, got " + std::to_string(threads));
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { work(); });
}

AdvancePool::~AdvancePool() {
  {
    std::lock_guard<std::mutex> lock(m_);
    stop_ = true;
  }
  cv_.notify_all();
  for (auto& t : threads_) t.join();
}

std::shared_ptr<AdvancePool::Job> AdvancePool::submit(std::vector<Simulation*> sims, std::vector<double> t_end, int a,
                                                      int b, std::string body) {
  if (t_end.size() != sims.size())
    throw std::invalid_argument("t_end must hold one end time per simulation (" + std::to_string(sims.size()) +
                                "), got " + std::to_string(t_end.size()));
  for (const double t : t_end)
    if (!std::isfinite(t)) throw std::invalid_argument("t_end must be finite, got " + std::to_string(t));
  auto job = std::make_shared<Job>();
  job->sims_ = std::move(sims);
  job->t_end_ = std::move(t_end);
  job->a_ = a;
  job->b_ = b;
  job->body_ = std::move(body);
  {
    std::lock_guard<std::mutex> lock(m_);
    queue_.push_back(job);
  }
  cv_.notify_one();
  return job;
}

void AdvancePool::work() {
  for (;;) {
    std::shared_ptr<Job> job;
    {
      std::unique_lock<std::mutex> lock(m_);
      cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping, nothing left
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    run(*job);
  }
}

bool AdvancePool::run_one() {
  std::shared_ptr<Job> job;
  {
    std::lock_guard<std::mutex> lock(m_);
    if (queue_.empty()) return false;
    job = std::move(queue_.front());
    queue_.pop_front();
  }
  run(*job);
  return true;
}

void AdvancePool::run(Job& job) {
  const size_t n = job.sims_.size();
  job.errors.assign(n, nullptr);
  job.seconds.assign(n, 0.0);
  try {
    std::vector<double> ends = job.t_end_;  // each end time's simulations in one call, in order
    std::sort(ends.begin(), ends.end());
    ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
    for (const double t : ends) {
      std::vector<Simulation*> group;
      std::vector<size_t> at;
      for (size_t i = 0; i < n; ++i)
        if (job.t_end_[i] == t) {
          group.push_back(job.sims_[i]);
          at.push_back(i);
        }
      std::vector<double> secs;
      const auto errs = run_batch(group, t, 1, &secs);
      for (size_t k = 0; k < at.size(); ++k) {
        job.errors[at[k]] = errs[k];
        job.seconds[at[k]] = secs[k];
      }
    }
    if (!job.body_.empty()) job.rows = Simulation::pair_readout(job.sims_, job.a_, job.b_, job.body_);
  } catch (...) {
    job.failure = std::current_exception();
  }
  {
    std::lock_guard<std::mutex> lock(job.m_);
    job.done_ = true;
  }
  job.cv_.notify_all();
}

}  // namespace coopsim
