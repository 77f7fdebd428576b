// One driver per simulation: two std::threads racing to advance one Simulation of the task's scene
// (task_scene.hpp) never both run it. Built with CMake's COOPSIM_BUILD_NATIVE_TESTS and run under
// ThreadSanitizer by scripts/test_threads.sh, so that a data race on the holder (or on the
// simulation behind it) is a failure even when the counts come out right.
//
// Three checks:
//   gated race  the first thread in waits inside the engine (a reference's first evaluation blocks)
//               until the other has tried: every time exactly one runs, the other gets
//               SimulationBusyError naming the holder's thread, and the steps are one driver's
//   free race   both threads advance at once with nothing to make them meet: one runs and the other
//               is refused, or they ran one after the other; never anything else, never a race
//   hold        a thread holding the run with a label (Simulation::hold) steps inside it; the
//               other's advance, reset and set_applied_forces are refused naming the label; after
//               the release the other drives
//
//   coopsim_one_driver [races]   (200 of each race) exit status 0: every check passed
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "coopsim/simulation.hpp"
#include "task_scene.hpp"

using namespace coopsim;
using namespace task_scene;

namespace {

// A bound on any wait for the other thread: a condition awaited, never a time measured.
constexpr auto kWait = std::chrono::seconds(120);

// A reference that wraps another; armed, its first evaluation blocks until open() (the thread that
// made it, holding the run, then waits inside the engine). An evaluation by a second thread while
// the first waits is counted in `concurrent`.
class Gate : public Reference {
 public:
  explicit Gate(std::shared_ptr<const Reference> inner) : inner_(std::move(inner)) {}
  int dof() const override { return inner_->dof(); }
  double t_start() const override { return inner_->t_start(); }
  double t_end() const override { return inner_->t_end(); }
  void evaluate(double t, double* q, double* qd, double* qdd) const override {
    {
      std::unique_lock<std::mutex> lock(m_);
      if (waiting_) {
        ++concurrent_;
      } else if (armed_) {
        armed_ = false;
        waiting_ = true;
        cv_.wait_for(lock, kWait, [this] { return opened_; });
        waiting_ = false;
      }
    }
    inner_->evaluate(t, q, qd, qdd);
  }
  void arm() {
    std::lock_guard<std::mutex> lock(m_);
    armed_ = true;
    opened_ = false;
    concurrent_ = 0;
  }
  void open() {
    {
      std::lock_guard<std::mutex> lock(m_);
      opened_ = true;
    }
    cv_.notify_all();
  }
  int concurrent() const {
    std::lock_guard<std::mutex> lock(m_);
    return concurrent_;
  }

 private:
  std::shared_ptr<const Reference> inner_;
  mutable std::mutex m_;
  mutable std::condition_variable cv_;
  mutable bool armed_ = false, waiting_ = false, opened_ = false;
  mutable int concurrent_ = 0;
};

// Two threads released at once (C++17 has no std::barrier).
class StartLine {
 public:
  void arrive_and_wait() {
    std::unique_lock<std::mutex> lock(m_);
    if (++arrived_ == 2) cv_.notify_all();
    cv_.wait_for(lock, kWait, [this] { return arrived_ >= 2; });
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  int arrived_ = 0;
};

std::string text(std::thread::id id) {
  std::ostringstream out;
  out << id;
  return out.str();
}

std::string busy_message(const std::string& label, const std::string& thread) {
  return "this simulation is being run by '" + label + "' (thread " + thread +
         "); one driver at a time: pause or close it first";
}

// What one racing thread did: ran, or was refused (with the error's holder, thread and message).
struct Attempt {
  bool ran = false, busy = false;
  std::string holder, thread, message, other;  // other: another exception's message
  std::thread::id self;
};

Attempt attempt(Simulation& sim, long n, StartLine& start, Gate* gate) {
  Attempt a;
  a.self = std::this_thread::get_id();
  start.arrive_and_wait();
  try {
    sim.advance(n);
    a.ran = true;
  } catch (const SimulationBusyError& e) {
    a.busy = true;
    a.holder = e.holder();
    a.thread = e.thread();
    a.message = e.what();
  } catch (const std::exception& e) {
    a.other = e.what();
  }
  if (gate) gate->open();  // whoever is done lets the other through
  return a;
}

std::unique_ptr<Simulation> task_sim() {
  const Shared shared = make_shared_parts();
  return make_run({0.95, 0.30, 30 * kDeg, true, 2e-4}, shared);
}

int fail(const char* check, int rep, const std::string& why) {
  std::printf("one_driver: %s, race %d: %s\n", check, rep, why.c_str());
  return 1;
}

// Exactly one of two attempts ran and the other was refused naming the runner's thread.
std::string one_ran_one_refused(const Attempt& a, const Attempt& b) {
  if (!a.other.empty() || !b.other.empty()) return "another error: " + a.other + b.other;
  if (a.ran == b.ran) return a.ran ? "both ran" : "neither ran";
  const Attempt& winner = a.ran ? a : b;
  const Attempt& loser = a.ran ? b : a;
  if (!loser.busy) return "the loser was not refused";
  if (loser.holder != "another thread" || loser.thread != text(winner.self))
    return "the error names '" + loser.holder + "' (thread " + loser.thread + "), not the runner";
  if (loser.message != busy_message("another thread", text(winner.self))) return "message: " + loser.message;
  return "";
}

int gated_race(int races) {
  auto sim = task_sim();
  auto gate = std::make_shared<Gate>(sim->reference(1));
  sim->set_reference(1, gate);
  const long n = 25;
  int failed = 0;
  for (int rep = 0; rep < races && !failed; ++rep) {
    sim->reset();
    gate->arm();
    StartLine start;
    Attempt a, b;
    std::thread ta([&] { a = attempt(*sim, n, start, gate.get()); });
    std::thread tb([&] { b = attempt(*sim, n, start, gate.get()); });
    ta.join();
    tb.join();
    const std::string why = one_ran_one_refused(a, b);
    if (!why.empty()) failed += fail("gated race", rep, why);
    else if (gate->concurrent()) failed += fail("gated race", rep, "two threads stepped at once");
    else if (sim->step_count() != n)
      failed += fail("gated race", rep, std::to_string(sim->step_count()) + " steps, not one driver's " + std::to_string(n));
    else if (!sim->holder().empty()) failed += fail("gated race", rep, "still held by '" + sim->holder() + "'");
  }
  std::printf("one_driver: gated race x%d: %s\n", races, failed ? "FAILED" : "one ran, the other was refused, each time");
  return failed;
}

int free_race(int races) {
  auto sim = task_sim();
  const long n = 25;
  int failed = 0, met = 0;
  for (int rep = 0; rep < races && !failed; ++rep) {
    sim->reset();
    StartLine start;
    Attempt a, b;
    std::thread ta([&] { a = attempt(*sim, n, start, nullptr); });
    std::thread tb([&] { b = attempt(*sim, n, start, nullptr); });
    ta.join();
    tb.join();
    if (a.ran && b.ran) {  // one after the other
      if (sim->step_count() != 2 * n)
        failed += fail("free race", rep, "both ran but " + std::to_string(sim->step_count()) + " steps");
      continue;
    }
    ++met;
    const std::string why = one_ran_one_refused(a, b);
    if (!why.empty()) failed += fail("free race", rep, why);
    else if (sim->step_count() != n)
      failed += fail("free race", rep, std::to_string(sim->step_count()) + " steps, not one driver's " + std::to_string(n));
  }
  std::printf("one_driver: free race x%d: %s (they met %d times)\n", races, failed ? "FAILED" : "never both at once",
              met);
  return failed;
}

int hold() {
  auto sim = task_sim();
  const std::string label = "the live view at http://127.0.0.1:8080";
  std::mutex m;
  std::condition_variable cv;
  int stage = 0;  // 1: the driver holds the run; 2: the other has tried; 3: released
  std::string why;
  std::thread::id driver_id;
  auto wait_for = [&](int s) {
    std::unique_lock<std::mutex> lock(m);
    return cv.wait_for(lock, kWait, [&] { return stage >= s; });
  };
  auto to = [&](int s) {
    {
      std::lock_guard<std::mutex> lock(m);
      stage = s;
    }
    cv.notify_all();
  };
  std::thread driver([&] {
    driver_id = std::this_thread::get_id();
    {
      Simulation::Hold h = sim->hold(label);
      Simulation::Hold again = sim->hold("a nested driver");  // re-entrant on this thread
      sim->advance(10);
      again.release();
      to(1);
      wait_for(2);
      sim->advance(10);  // still held after the nested release
    }
    to(3);
  });
  if (!wait_for(1)) why = "the driver never held the run";
  std::thread::id holder_id;
  if (why.empty() && (sim->holder(&holder_id) != label || holder_id != driver_id))
    why = "holder() is '" + sim->holder() + "', not the label";
  const std::vector<std::pair<const char*, std::function<void()>>> calls = {
      {"advance", [&] { sim->advance(10); }},
      {"reset", [&] { sim->reset(); }},
      {"set_applied_forces", [&] { sim->set_applied_forces(0, VecN::Ones(6)); }},
      {"hold", [&] { sim->hold("the notebook"); }},
  };
  for (const auto& call : calls) {
    if (!why.empty()) break;
    try {
      call.second();
      why = std::string(call.first) + " ran while another thread held the run";
    } catch (const SimulationBusyError& e) {
      if (e.holder() != label || e.what() != busy_message(label, text(driver_id)))
        why = std::string(call.first) + ": " + e.what();
    }
  }
  to(2);
  driver.join();
  if (why.empty() && !sim->holder().empty()) why = "the hold was not released";
  if (why.empty()) {
    try {
      sim->advance(5);
    } catch (const std::exception& e) {
      why = std::string("after the release: ") + e.what();
    }
  }
  if (why.empty() && sim->step_count() != 25) why = std::to_string(sim->step_count()) + " steps, not 25";
  std::printf("one_driver: hold: %s\n", why.empty() ? "the other thread refused while held, free after" : why.c_str());
  return why.empty() ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const int races = argc > 1 ? std::atoi(argv[1]) : 200;
  const int failed = gated_race(races) + free_race(races) + hold();
  std::printf("one_driver: %d passed, %d failed\n", 3 - failed, failed);
  return failed ? 1 : 0;
}
