// Helpers the engine's sources share; internal (not installed, not part of the API).
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace coopsim::detail {

// Throws std::invalid_argument(msg) (Python's ValueError) unless ok.
inline void require(bool ok, const std::string& msg) {
  if (!ok) throw std::invalid_argument(msg);
}

// x as a message shows it: six significant digits.
inline std::string num(double x) {
  std::ostringstream s;
  s.precision(6);
  s << x;
  return s.str();
}

}  // namespace coopsim::detail
