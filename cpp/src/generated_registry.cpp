// Looks up closed-form dynamics compiled into the engine by robot name. The
// table is filled by the generated sources in cpp/generated, each of which
// registers itself through generated_table().
#include "coopsim/generated.hpp"

#include <map>

namespace coopsim {

std::map<std::string, const GeneratedDynamics*>& generated_table() {
  static std::map<std::string, const GeneratedDynamics*> table;
  return table;
}

const GeneratedDynamics* builtin_generated(const std::string& name) {
  auto& t = generated_table();
  auto it = t.find(name);
  return it == t.end() ? nullptr : it->second;
}

std::vector<std::string> builtin_generated_names() {
  std::vector<std::string> out;
  for (const auto& kv : generated_table()) out.push_back(kv.first);
  return out;
}

}  // namespace coopsim
