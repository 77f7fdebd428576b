// Simulations run side by side on threads (run_batch, cpp/src/batch.cpp).
#pragma once

#include <exception>
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

}  // namespace coopsim
