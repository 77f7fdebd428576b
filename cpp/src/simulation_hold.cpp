// One driver at a time: the simulation's holder, the thread that is advancing or changing the run
// (simulation.hpp's header comment). Every mutating call enters through Simulation::Entry (an
// implicit hold for its own duration) and a driver takes the run across many calls with
// Simulation::hold(label).
//
// The holder is an atomic thread id with a re-entrant depth. The id is taken by compare-and-swap
// and given back by a store, both under a mutex that also guards the label: a thread that finds
// the run held reads, under that mutex, the holder's id and label as one consistent pair. The
// holder's own re-entries take no lock: only the holder can have stored its id, so its load of
// the id sees it, and the depth is touched by the holder alone (atomic all the same, for a Hold
// released on another thread). The release's store and the next taker's swap, under the mutex,
// order everything the one driver did to the simulation before everything the next one does.
#include <sstream>
#include <string>

#include "coopsim/simulation.hpp"

namespace coopsim {

namespace {

std::string thread_text(std::thread::id id) {
  std::ostringstream out;
  out << id;
  return out.str();
}

const char* const kImplicit = "another thread";

}  // namespace

struct Simulation::Driver {
  std::atomic<std::thread::id> owner{std::thread::id()};  // std::thread::id(): nobody holds the run
  std::atomic<long> depth{0};                             // the holder's nested holds
  std::mutex m;                                           // guards label, and orders the taking
  std::string label;                                      // the holder's, written under m

  // Takes the run for this thread (or enters it again); throws SimulationBusyError if another holds it.
  void enter(const std::string* name) {
    const std::thread::id me = std::this_thread::get_id();
    if (owner.load(std::memory_order_acquire) == me) {
      depth.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    std::lock_guard<std::mutex> lock(m);
    std::thread::id none;
    if (!owner.compare_exchange_strong(none, me, std::memory_order_acq_rel)) throw SimulationBusyError(label, thread_text(none));
    depth.store(1, std::memory_order_relaxed);
    label = name ? *name : kImplicit;
  }

  void leave() noexcept {
    if (depth.fetch_sub(1, std::memory_order_acq_rel) != 1) return;
    std::lock_guard<std::mutex> lock(m);
    label.clear();
    owner.store(std::thread::id(), std::memory_order_release);
  }
};

std::shared_ptr<Simulation::Driver> Simulation::make_driver_() { return std::make_shared<Driver>(); }

SimulationBusyError::SimulationBusyError(const std::string& holder, const std::string& thread)
    : std::runtime_error("this simulation is being run by '" + holder + "' (thread " + thread +
                         "); one driver at a time: pause or close it first"),
      holder_(holder),
      thread_(thread) {}

Simulation::Entry::Entry(Driver& d) : driver_(d) { d.enter(nullptr); }

Simulation::Entry::~Entry() { driver_.leave(); }

Simulation::Hold& Simulation::Hold::operator=(Hold&& o) noexcept {
  if (this != &o) {
    if (driver_) driver_->leave();
    driver_ = std::move(o.driver_);
  }
  return *this;
}

Simulation::Hold::~Hold() {
  if (driver_) driver_->leave();
}

void Simulation::Hold::release() {
  if (!driver_) return;
  if (driver_->owner.load(std::memory_order_acquire) != std::this_thread::get_id())
    throw std::logic_error("a simulation's hold must be released by the thread that took it");
  std::shared_ptr<Driver> d = std::move(driver_);
  d->leave();
}

Simulation::Hold Simulation::hold(const std::string& label) {
  if (label.empty()) throw std::invalid_argument("label must not be empty: it names the driver to the others");
  driver_->enter(&label);
  return Hold(driver_);
}

std::string Simulation::holder(std::thread::id* thread) const {
  std::lock_guard<std::mutex> lock(driver_->m);  // the id and the label change together under it
  if (thread) *thread = driver_->owner.load(std::memory_order_acquire);
  return driver_->label;
}

void Simulation::set_profiling(bool on) {
  const Entry driving = enter_();
  data_.profiling = on;
}

}  // namespace coopsim
