// Looks up generated dynamics by name: the robots compiled into the engine
// (listed explicitly by the generated cpp/generated/registry.cpp, so a static
// link keeps them), code registered at run time from shared libraries, and
// libraries of the build cache found by name (generated_loader.cpp).
#include <map>
#include <mutex>
#include <stdexcept>

#include "coopsim/generated.hpp"

namespace coopsim {

namespace {

std::mutex& runtime_mutex() {
  static std::mutex m;
  return m;
}

std::map<std::string, std::shared_ptr<const GeneratedDynamics>>& runtime_table() {
  static std::map<std::string, std::shared_ptr<const GeneratedDynamics>> table;
  return table;
}

}  // namespace

const GeneratedDynamics* find_generated(const std::string& name) {
  static const std::vector<const GeneratedDynamics*> compiled = compiled_generated();
  for (const GeneratedDynamics* g : compiled)
    if (g->name == name) return g;
  {
    std::lock_guard<std::mutex> lock(runtime_mutex());
    auto it = runtime_table().find(name);
    if (it != runtime_table().end()) return it->second.get();
  }
  auto g = find_cached_generated(name);
  if (!g) return nullptr;
  std::lock_guard<std::mutex> lock(runtime_mutex());
  auto& slot = runtime_table()[name];
  if (!slot) slot = std::move(g);  // another thread may have loaded it meanwhile
  return slot.get();
}

std::vector<std::string> compiled_generated_names() {
  std::vector<std::string> out;
  for (const GeneratedDynamics* g : compiled_generated()) out.push_back(g->name);
  return out;
}

void register_generated(std::shared_ptr<const GeneratedDynamics> gen) {
  if (!gen) throw std::invalid_argument("register_generated: no generated dynamics given");
  for (const GeneratedDynamics* g : compiled_generated())
    if (g->name == gen->name)
      throw std::invalid_argument("register_generated: '" + gen->name + "' is compiled into the engine");
  std::lock_guard<std::mutex> lock(runtime_mutex());
  runtime_table()[gen->name] = std::move(gen);
}

}  // namespace coopsim
