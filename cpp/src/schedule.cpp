// A schedule run by the engine (schedule.hpp): its checks, its steps' pieces, the failures' reasons.
#include "coopsim/schedule.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "coopsim/world.hpp"
#include "internal.hpp"

namespace coopsim {

namespace {

std::string fixed(double x, int digits) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, x);
  return buf;
}

bool match(const std::string& pattern, const std::string& name) {
  if (pattern == "*") return true;
  if (!pattern.empty() && pattern.back() == '*')
    return name.compare(0, pattern.size() - 1, pattern, 0, pattern.size() - 1) == 0;
  if (!pattern.empty() && pattern.front() == '*')
    return name.size() >= pattern.size() - 1 &&
           name.compare(name.size() - (pattern.size() - 1), pattern.size() - 1, pattern, 1) == 0;
  return pattern == name;
}

std::string step_label(const Schedule& s, size_t k) {
  return "schedule step " + std::to_string(k + 1) + " ('" + s.steps[k].name + "')";
}

const std::string& body_name(const Simulation& sim, int id) { return sim.world()->body(id).name; }

std::string robot_name(const Simulation& sim, int i) { return "robot " + std::to_string(i) + " ('" + sim.robot(i).name() + "')"; }

bool holds(const Simulation& sim, const ScheduleCondition& c) { return sim.holding(c.robot) == c.body; }

// Why condition c is false now: `kind` hold (it was true), wait (within `timeout` s) or at_end.
std::string why_not(Simulation& sim, const ScheduleCondition& c, const std::string& kind, double timeout) {
  const std::string who = robot_name(sim, c.robot);
  const int held = sim.holding(c.robot);
  const std::string within = kind == "wait" ? " within " + detail::num(timeout) + " s" : "";
  if (c.body < 0) return who + " did not let go of " + body_name(sim, held) + within;
  if (held >= 0) return who + " holds " + body_name(sim, held) + ", not " + body_name(sim, c.body);
  if (kind == "hold") {
    std::string last;
    for (const GraspEvent& e : sim.grasp_events())
      if (e.robot == c.robot && !e.grasp) last = " (" + e.reason + " at t = " + fixed(e.t, 4) + " s)";
    return who + " let go of " + body_name(sim, c.body) + last;
  }
  const GraspCheck g = sim.grasp_check(c.robot, c.body);
  std::string failed;
  const std::pair<bool, const char*> parts[] = {{g.closing, "closing"}, {g.aligned, "aligned"},
                                                {g.touching, "touching"}, {g.in_pads, "in_pads"}, {g.slow, "slow"}};
  for (const auto& p : parts)
    if (!p.first) failed += (failed.empty() ? "" : ", ") + std::string(p.second);
  return who + " did not grasp " + body_name(sim, c.body) + within + ": the clamp rule's " +
         (failed.empty() ? "hold time" : failed) + " failed (angle " + fixed(g.angle * 180.0 / M_PI, 1) +
         " deg, gaps " + fixed(g.gap_fixed * 1e3, 1) + " and " + fixed(g.gap_moving * 1e3, 1) + " mm, speed " +
         fixed(g.speed, 3) + " m/s)";
}

void check_condition(const Simulation& sim, const ScheduleCondition& c, const std::string& where) {
  if (c.robot < 0 || c.robot >= sim.robot_count())
    throw std::invalid_argument(where + ": robot " + std::to_string(c.robot) + " out of range (0 .. " +
                                std::to_string(sim.robot_count() - 1) + ")");
  if (c.body < 0) return;
  const World* w = sim.world().get();
  if (!w) throw std::invalid_argument(where + ": a body held, but the simulation has no world");
  if (c.body >= w->body_count() || w->body(c.body).kind != BodyKind::Free)
    throw std::invalid_argument(where + ": body " + std::to_string(c.body) + " is not a free body of the world");
}

void check_action(const Simulation& sim, const ScheduleAction& a, const std::string& where) {
  const int n = sim.robot_count();
  auto robot_ok = [&](int i) {
    if (i < 0 || i >= n)
      throw std::invalid_argument(where + ": robot " + std::to_string(i) + " out of range (0 .. " +
                                  std::to_string(n - 1) + ")");
  };
  switch (a.kind) {
    case ScheduleAction::kSetController:
      robot_ok(a.robot);
      if (!a.controller) throw std::invalid_argument(where + ": no controller");
      try {
        a.controller->check(sim.robot(a.robot));
      } catch (const std::exception& e) {
        throw std::invalid_argument(where + ": " + e.what());
      }
      break;
    case ScheduleAction::kSetReference:
      robot_ok(a.robot);
      if (!a.reference) throw std::invalid_argument(where + ": no reference");
      if (a.reference->dof() != sim.robot(a.robot).dof())
        throw std::invalid_argument(where + ": the reference has " + std::to_string(a.reference->dof()) +
                                    " joints, robot " + std::to_string(a.robot) + " " +
                                    std::to_string(sim.robot(a.robot).dof()));
      break;
    case ScheduleAction::kAddCooperative:
      if (!a.cooperative) throw std::invalid_argument(where + ": no cooperative controller");
      if (a.robots.empty()) throw std::invalid_argument(where + ": robots must name at least one robot");
      for (int i : a.robots) robot_ok(i);
      break;
    case ScheduleAction::kRemoveCooperative:
      break;  // the group's existence depends on the adds before it: checked in run order
    case ScheduleAction::kSetBodyWrench: {
      const World* w = sim.world().get();
      if (!w) throw std::invalid_argument(where + ": the simulation has no world");
      if (a.body < 0 || a.body >= w->body_count() || w->body(a.body).kind != BodyKind::Free)
        throw std::invalid_argument(where + ": body " + std::to_string(a.body) + " is not a free body of the world");
      if (!a.wrench.allFinite()) throw std::invalid_argument(where + ": the wrench must be finite");
      break;
    }
    case ScheduleAction::kRelease:
      robot_ok(a.robot);
      break;
    default:
      throw std::invalid_argument(where + ": unknown action kind " + std::to_string(static_cast<int>(a.kind)));
  }
}

}  // namespace

const char* ScheduleAction::kind_name(Kind k) {
  switch (k) {
    case kSetController: return "set_controller";
    case kSetReference: return "set_reference";
    case kAddCooperative: return "add_cooperative";
    case kRemoveCooperative: return "remove_cooperative";
    case kSetBodyWrench: return "set_body_wrench";
    case kRelease: return "release";
  }
  return "unknown";
}

bool ContactRule::matches(const std::string& x, const std::string& y, double begin) const {
  if (!(begin >= from && begin <= to)) return false;
  return (match(a, x) && match(b, y)) || (match(a, y) && match(b, x));
}

void check_schedule(const Simulation& sim, const Schedule& s) {
  double last = sim.time();
  int groups = 0;  // cooperative groups the schedule adds before each step
  for (size_t k = 0; k < s.steps.size(); ++k) {
    const ScheduleStep& st = s.steps[k];
    const std::string at = step_label(s, k);
    if (st.name.empty()) throw std::invalid_argument(at + ": the step needs a name");
    if (!std::isfinite(st.until))
      throw std::invalid_argument(at + ": until must be a finite time (s), got " + detail::num(st.until));
    if (st.until < last - 1e-9 * sim.options().dt)
      throw std::invalid_argument(at + ": until " + detail::num(st.until) + " s is before " +
                                  (k == 0 ? "now (" : "the previous step's end (") + detail::num(last) + " s)");
    last = std::max(last, st.until);
    if (!(std::isfinite(st.every) && st.every >= 0.0))
      throw std::invalid_argument(at + ": every must be a finite time >= 0 s, got " + detail::num(st.every));
    for (size_t j = 0; j < st.actions.size(); ++j) {
      const ScheduleAction& a = st.actions[j];
      const std::string where = at + ", action " + std::to_string(j + 1) + " (" +
                                ScheduleAction::kind_name(a.kind) + ")";
      check_action(sim, a, where);
      if (a.kind == ScheduleAction::kAddCooperative) ++groups;
      if (a.kind == ScheduleAction::kRemoveCooperative) {
        if (a.group < 0 && groups == 0)
          throw std::invalid_argument(where + ": no group to remove (the schedule added none before it)");
        if (a.group >= sim.cooperative_count() + groups)
          throw std::invalid_argument(where + ": group " + std::to_string(a.group) + " out of range");
      }
    }
    const std::pair<const std::vector<ScheduleCondition>*, const char*> lists[] = {
        {&st.hold, "hold"}, {&st.wait, "wait"}, {&st.at_end, "at_end"}, {&st.record, "record"}};
    for (const auto& l : lists)
      for (size_t j = 0; j < l.first->size(); ++j)
        check_condition(sim, (*l.first)[j], at + ", " + l.second + " condition " + std::to_string(j + 1));
  }
  if (s.check_contacts && !sim.world()) throw std::invalid_argument("the schedule checks contacts, but the simulation has no world");
  for (size_t j = 0; j < s.allowed.size(); ++j) {
    const ContactRule& r = s.allowed[j];
    if (r.a.empty() || r.b.empty())
      throw std::invalid_argument("allowed contact " + std::to_string(j + 1) + ": empty body pattern");
    if (std::isnan(r.from) || std::isnan(r.to) || r.from > r.to)
      throw std::invalid_argument("allowed contact " + std::to_string(j + 1) + ": from and to must be times with from <= to");
  }
}

ScheduleOutcome run_schedule(Simulation& sim, const Schedule& s, long contacts_seen,
                             const std::function<void()>& between) {
  Simulation::Hold held = sim.hold("a schedule");
  check_schedule(sim, s);
  ScheduleOutcome out;
  const World* w = sim.world().get();
  const long n_events = w ? static_cast<long>(w->events().size()) : 0;
  if (contacts_seen < 0 || contacts_seen > n_events)
    throw std::invalid_argument("contacts_seen must be 0 .. " + std::to_string(n_events) + " (the events so far), got " +
                                std::to_string(contacts_seen));
  out.contacts_seen = contacts_seen;
  const double dt = sim.options().dt;
  constexpr long kBetween = 4096;  // steps between calls of between()
  long since_between = 0;

  auto fail = [&](size_t k, const char* kind, double t, std::string reason, int condition = -1) {
    out.failed_step = static_cast<int>(k);
    out.kind = kind;
    out.t = t;
    out.reason = std::move(reason);
    out.condition = condition;
    out.times.back()[1] = sim.time();
  };
  // the contacts that began since the last look, against the rules: false when one is not allowed
  auto contacts_ok = [&](size_t k) {
    if (!s.check_contacts || !w) return true;
    const std::vector<ContactEvent>& ev = w->events();
    for (; out.contacts_seen < static_cast<long>(ev.size()); ++out.contacts_seen) {
      const ContactEvent& e = ev[out.contacts_seen];
      const std::string &a = w->body(e.a).name, &b = w->body(e.b).name;
      bool ok = false;
      for (const ContactRule& r : s.allowed)
        if (r.matches(a, b, e.begin)) {
          ok = true;
          break;
        }
      if (!ok) {
        fail(k, "contact", e.begin, "unexpected contact between " + a + " and " + b);
        out.bodies = {a, b};
        return false;
      }
    }
    return true;
  };
  auto hold_ok = [&](size_t k) {
    const ScheduleStep& st = s.steps[k];
    for (size_t j = 0; j < st.hold.size(); ++j)
      if (!holds(sim, st.hold[j])) {
        fail(k, "hold", sim.time(), why_not(sim, st.hold[j], "hold", 0.0), static_cast<int>(j));
        return false;
      }
    return true;
  };
  auto all = [&](const std::vector<ScheduleCondition>& cs) {
    for (const ScheduleCondition& c : cs)
      if (!holds(sim, c)) return false;
    return true;
  };
  std::vector<char> recorded;

  for (size_t k = 0; k < s.steps.size(); ++k) {
    const ScheduleStep& st = s.steps[k];
    out.times.push_back({sim.time(), sim.time()});
    for (size_t j = 0; j < st.actions.size(); ++j) {
      const ScheduleAction& a = st.actions[j];
      try {
        switch (a.kind) {
          case ScheduleAction::kSetController: sim.set_controller(a.robot, a.controller); break;
          case ScheduleAction::kSetReference: sim.set_reference(a.robot, a.reference); break;
          case ScheduleAction::kAddCooperative: out.groups.push_back(sim.add_cooperative(a.cooperative, a.robots)); break;
          case ScheduleAction::kRemoveCooperative: sim.remove_cooperative(a.group >= 0 ? a.group : out.groups.back()); break;
          case ScheduleAction::kSetBodyWrench: sim.set_body_wrench(a.body, a.wrench); break;
          case ScheduleAction::kRelease: sim.release(a.robot); break;
        }
      } catch (const std::exception& e) {
        throw std::invalid_argument(step_label(s, k) + " at t = " + fixed(sim.time(), 4) + " s, action " +
                                    std::to_string(j + 1) + " (" + ScheduleAction::kind_name(a.kind) + "): " + e.what());
      }
    }
    recorded.assign(st.record.size(), 0);
    const double t0 = sim.time();
    const long total = sim.steps_until(st.until);
    const long every = st.every > 0.0 ? std::max(1L, static_cast<long>(std::floor(st.every / dt + 1e-9))) : std::max(1L, total);
    sim.reserve(total);
    bool waited = !st.wait.empty() && all(st.wait);
    long done = 0;
    while (!waited && done < total) {
      const long c = std::min(every, total - done);
      // the piece in runs of at most kBetween steps, between() after each full run (a Ctrl-C: what it throws
      // propagates as it is, the state and log consistent)
      for (long left = c; left > 0;) {
        const long a = std::min(left, kBetween - since_between);
        try {
          sim.advance(a);
        } catch (const std::exception& e) {
          if (!hold_ok(k)) return out;  // a clamp let go, and a law holding both refused it
          fail(k, "error", sim.time(), e.what());
          out.error = std::current_exception();
          return out;
        }
        left -= a;
        done += a;
        since_between += a;
        if (since_between >= kBetween) {
          since_between = 0;
          if (between) {
            out.times.back()[1] = sim.time();
            between();
          }
        }
      }
      if (!hold_ok(k) || !contacts_ok(k)) return out;
      for (size_t j = 0; j < st.record.size(); ++j)
        if (!recorded[j] && holds(sim, st.record[j])) {
          recorded[j] = 1;
          ScheduleRecord r;
          r.step = static_cast<int>(k);
          r.condition = static_cast<int>(j);
          r.t = sim.time();
          r.q = sim.q(st.record[j].robot);
          if (st.record[j].body >= 0) r.pose = sim.body_state(st.record[j].body).pose;
          out.records.push_back(std::move(r));
        }
      if (!st.wait.empty() && all(st.wait)) waited = true;
    }
    out.times.back()[1] = sim.time();
    if (!st.wait.empty() && !waited) {
      for (size_t j = 0; j < st.wait.size(); ++j)
        if (!holds(sim, st.wait[j])) {
          fail(k, "wait", sim.time(), why_not(sim, st.wait[j], "wait", sim.time() - t0), static_cast<int>(j));
          return out;
        }
    }
    for (size_t j = 0; j < st.at_end.size(); ++j)
      if (!holds(sim, st.at_end[j])) {
        fail(k, "at_end", sim.time(), why_not(sim, st.at_end[j], "at_end", 0.0), static_cast<int>(j));
        return out;
      }
  }
  return out;
}

}  // namespace coopsim
