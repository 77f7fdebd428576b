// run_batch with worlds on several threads, and an AdvancePool's chunks (its thread and the caller's), give bit for bit what the
// same simulations give one by one. Built with CMake's COOPSIM_BUILD_NATIVE_TESTS and run under ThreadSanitizer by
// scripts/test_threads.sh (COOPSIM_SANITIZE=thread), so that a data race between the threads of a
// batch is a failure even when it happens not to change a result.
//
// The scene is the cooperative task's (coopsim.tasks.scene), built in C++ in task_scene.hpp: SCARA #2
// grasps the bar and carries it, SCARA #1 presses its clamp onto the container.
//
//   coopsim_batch_threads [runs] [t_end]   (6 runs of 3 s) exit status 0: every run grasps the bar
//                                          and every batch is bit-equal to the runs one by one
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "coopsim/batch.hpp"
#include "coopsim/simulation.hpp"
#include "task_scene.hpp"

using namespace coopsim;
using namespace task_scene;

namespace {

// Everything a run leaves: its log, the bodies' log, contacts, grasps, metrics, divergence.
struct Outcome {
  std::vector<double> numbers;
  std::string text;
  long grasps = 0, contacts = 0;
};

void put(std::vector<double>& v, const LogColumn& c) {
  v.push_back(static_cast<double>(c.rows()));
  if (c.rows()) v.insert(v.end(), c.data(), c.data() + c.rows() * c.width());
}

Outcome outcome(const Simulation& s, const std::exception_ptr& error) {
  Outcome o;
  auto& v = o.numbers;
  v.push_back(static_cast<double>(s.step_count()));
  put(v, s.log_t());
  for (int i = 0; i < s.robot_count(); ++i) {
    for (const LogColumn& c : s.log(i).columns) put(v, c);
    put(v, s.log(i).grasp);
    const TrackingMetrics& m = s.metrics(i);
    v.push_back(static_cast<double>(m.steps));
    for (const VecN* x : {&m.sum_sq_error, &m.max_abs_error, &m.max_abs_tau, &s.q(i), &s.qd(i), &s.tau(i)})
      v.insert(v.end(), x->data(), x->data() + x->size());
  }
  for (const LogColumn& c : s.body_log()) put(v, c);
  for (const LoggedContact& lc : s.contact_log()) {
    const ContactPoint& p = lc.contact;
    v.insert(v.end(), {lc.t, double(p.a), double(p.b), p.depth, double(p.solver)});
    for (const Eigen::Vector3d* x : {&p.point_a, &p.point_b, &p.normal, &p.force}) v.insert(v.end(), x->data(), x->data() + 3);
  }
  for (const ContactEvent& e : s.world()->events())
    v.insert(v.end(), {double(e.a), double(e.b), e.begin, e.end, e.peak_force, e.max_depth, double(e.steps)});
  for (const GraspEvent& g : s.grasp_events()) {
    v.insert(v.end(), {g.t, double(g.robot), double(g.body), double(g.grasp)});
    o.text += g.reason + ";";
    o.grasps += g.grasp;
  }
  o.contacts = static_cast<long>(s.world()->events().size());
  if (error) {
    try {
      std::rethrow_exception(error);
    } catch (const std::exception& e) {
      o.text += std::string("error: ") + e.what();
    }
  }
  return o;
}

bool same(const Outcome& a, const Outcome& b) {
  return a.text == b.text && a.numbers.size() == b.numbers.size() &&
         std::memcmp(a.numbers.data(), b.numbers.data(), a.numbers.size() * sizeof(double)) == 0;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  const int runs = argc > 1 ? std::atoi(argv[1]) : 6;
  const double t_end = argc > 2 ? std::atof(argv[2]) : 3.0;
  // the task's region of bar starts: x 0.90-1.00, y 0.25-0.35, yaw 15-45 deg
  std::vector<RunSpec> specs;
  for (int k = 0; k < runs; ++k) {
    const double u = runs > 1 ? double(k) / (runs - 1) : 0.5;
    specs.push_back({0.90 + 0.10 * u, 0.35 - 0.10 * u, (15 + 30 * u) * kDeg, k % 2 == 0, k % 3 == 2 ? 1e-4 : 2e-4});
  }
  const Shared shared = make_shared_parts();
  auto build = [&]() {
    std::vector<std::unique_ptr<Simulation>> sims;
    for (const RunSpec& s : specs) sims.push_back(make_run(s, shared));
    return sims;
  };

  // one by one, on this thread
  auto t0 = std::chrono::steady_clock::now();
  std::vector<Outcome> serial;
  {
    auto sims = build();
    for (auto& s : sims) {
      std::exception_ptr e;
      try {
        s->advance(s->steps_until(t_end));
      } catch (...) {
        e = std::current_exception();
      }
      serial.push_back(outcome(*s, e));
    }
  }
  std::printf("batch_threads: %d runs of %.2f s one by one: %.2f s wall\n", runs, t_end, seconds_since(t0));
  long grasps = 0, contacts = 0;
  for (size_t i = 0; i < serial.size(); ++i) {
    grasps += serial[i].grasps;
    contacts += serial[i].contacts;
    std::printf("  run %zu: %s, dt %.0e: %ld grasp(s), %ld contact events%s%s\n", i,
                specs[i].computed_torque ? "generated dynamics, computed torque" : "numeric dynamics, #1 by PID",
                specs[i].dt,
                serial[i].grasps, serial[i].contacts, serial[i].text.empty() ? "" : ", events: ",
                serial[i].text.c_str());
  }
  // three checks: the runs grasp and touch, the batch on 2 threads, the batch on 3
  int failed = 0;
  if (grasps < runs || contacts == 0) {
    std::printf("batch_threads: every run should grasp the bar, and things should touch (grasps %ld, "
                "contact events %ld)\n", grasps, contacts);
    ++failed;
  }

  // the same runs as batches on 2 and 3 threads (3: more threads than this machine's cores, so
  // that they are preempted mid-step)
  for (int threads : {2, 3}) {
    auto sims = build();
    std::vector<Simulation*> ptrs;
    for (auto& s : sims) ptrs.push_back(s.get());
    t0 = std::chrono::steady_clock::now();
    const std::vector<std::exception_ptr> errors = run_batch(ptrs, t_end, threads);
    const double wall = seconds_since(t0);
    int differ = 0;
    for (size_t i = 0; i < sims.size(); ++i) {
      if (!same(outcome(*sims[i], errors[i]), serial[i])) {
        std::printf("  run %zu on %d threads differs from the same run alone\n", i, threads);
        ++differ;
      }
    }
    std::printf("batch_threads: run_batch on %d threads: %.2f s wall, %s\n", threads, wall,
                differ ? "DIFFERENT" : "bit-equal to the runs one by one");
    failed += differ > 0;
  }
  // the same runs through an AdvancePool of 1 thread and the caller's (AdvancePool::run_one, as the vector
  // environment's pipeline runs them), in chunks of two handed over one after the other, each chunk advanced
  // in two legs (half-way, then to the end) as a vector environment's steps are
  {
    auto sims = build();
    std::vector<std::exception_ptr> errors(sims.size());
    t0 = std::chrono::steady_clock::now();
    {
      AdvancePool pool(1);
      for (const double t : {t_end / 2, t_end}) {
        std::vector<std::pair<size_t, std::shared_ptr<AdvancePool::Job>>> jobs;
        for (size_t i = 0; i < sims.size(); i += 2) {
          std::vector<Simulation*> chunk;
          for (size_t k = i; k < std::min(sims.size(), i + 2); ++k) chunk.push_back(sims[k].get());
          jobs.emplace_back(i, pool.submit(chunk, std::vector<double>(chunk.size(), t)));
        }
        while (pool.run_one()) {
        }
        for (auto& [i, job] : jobs) {
          job->wait();
          for (size_t k = 0; k < job->errors.size(); ++k)
            if (job->errors[k] && !errors[i + k]) errors[i + k] = job->errors[k];
        }
      }
    }
    const double wall = seconds_since(t0);
    int differ = 0;
    for (size_t i = 0; i < sims.size(); ++i) {
      if (!same(outcome(*sims[i], errors[i]), serial[i])) {
        std::printf("  run %zu through the pool differs from the same run alone\n", i);
        ++differ;
      }
    }
    std::printf("batch_threads: AdvancePool of 1 thread and the caller, chunks of 2 in two legs: %.2f s wall, %s\n", wall,
                differ ? "DIFFERENT" : "bit-equal to the runs one by one");
    failed += differ > 0;
  }
  std::printf("batch_threads: %d passed, %d failed\n", 4 - failed, failed);
  return failed ? 1 : 0;
}
