// Native timing of the dynamics, called from C++ with no Python in between.
//
// Reads robot tables written by benchmarks/bench_dynamics.py (one robot per
// block, see read_robot) and prints, per robot and backend, the median ns per
// call over repeats of: mass matrix, C + G, forward dynamics, inverse
// dynamics, one RK4 step. Output lines: "name backend what ns".
#include <algorithm>
#include <chrono>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "coopsim/generated.hpp"
#include "coopsim/integrator.hpp"
#include "coopsim/robot.hpp"

using namespace coopsim;

namespace {

Robot read_robot(std::istream& in) {
  std::string name, types;
  int n;
  in >> name >> n >> types;
  std::vector<Link> links(n);
  for (int k = 0; k < n; ++k) {
    Link& L = links[k];
    L.type = types[k] == 'P' ? JointType::Prismatic : JointType::Revolute;
    in >> L.dh.theta >> L.dh.d >> L.dh.a >> L.dh.alpha >> L.com.theta >> L.com.d >> L.com.a >> L.com.alpha >> L.mass;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) in >> L.inertia(i, j);
    in >> L.friction >> L.q_min >> L.q_max >> L.tau_max;
  }
  Eigen::Vector3d g, p;
  double yaw;
  in >> g.x() >> g.y() >> g.z() >> p.x() >> p.y() >> p.z() >> yaw;
  Tool tool;
  Eigen::Matrix4d T;
  in >> tool.link;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) in >> T(i, j);
  tool.offset.matrix() = T;
  in >> tool.second_link >> tool.second_point.x() >> tool.second_point.y() >> tool.second_point.z();
  if (!in) throw std::runtime_error("malformed robot table");
  return Robot(links, g, p, yaw, tool, name);
}

volatile double sink = 0;

template <class F>
double time_ns(F&& f, int calls, int repeats) {
  std::vector<double> t;
  for (int r = 0; r < repeats; ++r) {
    const auto a = std::chrono::steady_clock::now();
    for (int i = 0; i < calls; ++i) f(i);
    const auto b = std::chrono::steady_clock::now();
    t.push_back(std::chrono::duration<double, std::nano>(b - a).count() / calls);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

void bench(const Robot& robot, const std::string& backend, int calls, int repeats) {
  const int n = robot.dof();
  const int S = 256;
  std::mt19937 gen(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<VecN> q(S, VecN(n)), qd(S, VecN(n)), qdd(S, VecN(n)), tau(S, VecN(n));
  for (int s = 0; s < S; ++s)
    for (int j = 0; j < n; ++j) {
      const Link& L = robot.links()[j];
      const double lo = std::isfinite(L.q_min) ? L.q_min : -3.0, hi = std::isfinite(L.q_max) ? L.q_max : 3.0;
      q[s][j] = lo + (hi - lo) * 0.5 * (u(gen) + 1.0);
      qd[s][j] = u(gen);
      qdd[s][j] = u(gen);
      tau[s][j] = u(gen);
    }
  Workspace ws;
  MatN M;
  VecN out;
  auto report = [&](const char* what, double ns) {
    std::cout << robot.name() << " " << backend << " " << what << " " << ns << "\n";
  };
  report("mass_matrix", time_ns([&](int i) {
           robot.mass_matrix(q[i % S].data(), ws, M);
           sink = sink + M(0, 0);
         }, calls, repeats));
  report("coriolis_plus_gravity", time_ns([&](int i) {
           robot.rnea(q[i % S].data(), qd[i % S].data(), nullptr, ws, out, 1.0, false);
           sink = sink + out[0];
         }, calls, repeats));
  report("forward_dynamics", time_ns([&](int i) {
           robot.forward_dynamics(q[i % S].data(), qd[i % S].data(), tau[i % S].data(), nullptr, ws, out);
           sink = sink + out[0];
         }, calls, repeats));
  report("inverse_dynamics", time_ns([&](int i) {
           robot.inverse_dynamics(q[i % S].data(), qd[i % S].data(), qdd[i % S].data(), nullptr, ws, out);
           sink = sink + out[0];
         }, calls, repeats));
  VecN qs = q[0], qds = qd[0];
  report("rk4_step", time_ns([&](int i) {
           if (i % S == 0) {  // restart from a sane state now and then
             qs = q[i % S];
             qds = qd[i % S];
           }
           rk4_step(robot, ws, qs, qds, tau[i % S].data(), nullptr, 2e-4, true);
           sink = sink + qs[0];
         }, calls, repeats));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::cerr << "usage: coopsim_bench TABLES [calls] [repeats]\n";
    return 2;
  }
  const int calls = argc > 2 ? std::stoi(argv[2]) : 20000;
  const int repeats = argc > 3 ? std::stoi(argv[3]) : 7;
#ifdef COOPSIM_OPTIMISED
  std::cout << "# build optimised\n";
#else
  std::cout << "# build NOT optimised: figures do not count\n";
#endif
  std::ifstream in(argv[1]);
  int count;
  in >> count;
  for (int r = 0; r < count; ++r) {
    Robot robot = read_robot(in);
    bench(robot, "numeric", calls, repeats);
    if (const GeneratedDynamics* g = find_generated(robot.name())) {
      const Robot gen = robot.with_generated(std::shared_ptr<const GeneratedDynamics>(g, [](const GeneratedDynamics*) {}));
      bench(gen, "generated", calls, repeats);
    }
  }
  return 0;
}
