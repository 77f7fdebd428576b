// The GIL released around an engine call (NoGil, for py::gil_scoped_release), the time counted per
// thread (released_seconds); a Python callback inside takes it back with GilAgain, which pauses the count.
#pragma once

#include <pybind11/pybind11.h>

#include <chrono>

namespace coopsim::py_nogil {

using Clock = std::chrono::steady_clock;

struct Count {
  long long ns = 0;  // counted so far on this thread
  int depth = 0;     // NoGil sections open (nested: the outer one counts)
  Clock::time_point since{};
  bool on = false;   // counting now (inside a section, not in a callback)
  static Count& mine() { thread_local Count c; return c; }
  void start() { since = Clock::now(); on = true; }
  void stop() {
    if (on) ns += std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - since).count();
    on = false;
  }
};

struct NoGil {
  NoGil() { if (Count::mine().depth++ == 0) Count::mine().start(); }
  ~NoGil() { if (--Count::mine().depth == 0) Count::mine().stop(); }  // before release's destructor
  pybind11::gil_scoped_release release;
};

struct GilAgain {  // members: resume runs after acquire's destructor has released the GIL again
  struct Resume { ~Resume() { if (Count::mine().depth > 0) Count::mine().start(); } } resume;
  pybind11::gil_scoped_acquire acquire;
  GilAgain() { Count::mine().stop(); }
};

inline double released_seconds() { return static_cast<double>(Count::mine().ns) * 1e-9; }

// Whether the calling thread is Python's main thread, the only one its signal handlers run on: a Ctrl-C
// check between an engine call's chunks takes the GIL back for nothing on another thread (a sweep's worker,
// which would wait for it while other threads run Python). Call with the GIL held.
inline bool on_main_thread() {
  static const unsigned long main_ident =
      pybind11::module_::import("threading").attr("main_thread")().attr("ident").cast<unsigned long>();
  return PyThread_get_thread_ident() == main_ident;
}

}  // namespace coopsim::py_nogil
