// A schedule: a task's sequence run by the engine in one call. Its steps each make their changes to
// the run (actions: install a controller, a reference or a cooperative group, remove a group, set a
// free body's wrench, release a grasp), then advance to a time in pieces, checking after each piece
// what the task requires (a robot still holds its body; the contacts that began are allowed ones),
// waiting for a condition with a timeout (a grasp, a release) and recording when conditions first
// come true (a grasp's time, the robot's joints and the body's pose then). What a task sequenced in
// Python does between engine calls (the phases, the waits, the event checks, the disturbances'
// switches), without handing the run back between steps: the GIL stays released for the whole
// sequence.
//
// The pieces are those of Simulation::run_until: a step of `every` s advances in pieces of that
// many whole steps (at least one) counted from its start, the last one shorter; every = 0: the step
// in one piece. A caller that advanced piece by piece and checked between pieces ran the same steps
// and stops at the same time, so a sequence moved into a schedule gives the same run.
//
// After each piece, in order: the contacts that began since the last look, each against the
// schedule's allowed rules (the first not allowed fails the run: "contact"); the step's hold
// conditions (one false fails it: "hold"); its record conditions (each recorded at the first piece
// end at which it is true); its wait conditions (all true: the step ends). At the step's end its
// at_end conditions must be true ("at_end"), and a wait step whose conditions did not all come true
// by `until` fails ("wait"). An engine error while advancing (a DivergenceError, a cooperative
// law refusing robots that no longer hold one body) ends the run with kind "error": a hold
// condition false then is the failure instead (a clamp let go, and the law refused it).
//
// A failure is an outcome, not an exception: the step, the time (for a contact, when it began), the
// kind, the condition or the bodies, and a one-line reason. A bad schedule (a robot or body out of
// range, an action without its argument, times going back) is std::invalid_argument before anything
// runs, naming the step and the action; an action the simulation refuses when its step comes (a
// controller already driving another robot) is std::invalid_argument naming the step, its time and
// the action, with the run stopped at that step's start.
#pragma once

#include <array>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "coopsim/simulation.hpp"

namespace coopsim {

// A change a step makes to the run at its start (Simulation's calls of those names).
struct ScheduleAction {
  enum Kind : int { kSetController, kSetReference, kAddCooperative, kRemoveCooperative, kSetBodyWrench, kRelease };
  Kind kind = kSetReference;
  int robot = -1;                                      // set_controller, set_reference, release
  std::shared_ptr<Controller> controller;              // set_controller
  std::shared_ptr<const Reference> reference;          // set_reference
  std::shared_ptr<CooperativeController> cooperative;  // add_cooperative, with `robots`
  std::vector<int> robots;
  int group = -1;  // remove_cooperative: the group's index; -1: the last one this schedule added
  int body = -1;   // set_body_wrench: a free body's id, with `wrench` (world force N, moment N m)
  Vec6 wrench = Vec6::Zero();
  // "set_controller", "set_reference", ...
  static const char* kind_name(Kind k);
};

// Robot `robot` holds body `body` (a free body's id; -1: holds nothing).
struct ScheduleCondition {
  int robot = 0;
  int body = -1;
};

// A contact allowed between a body whose name matches `a` and one whose name matches `b` (either
// way round) beginning at a time within [from, to] s. A pattern is a name, "prefix*", "*suffix" or "*".
struct ContactRule {
  std::string a, b;
  double from = -std::numeric_limits<double>::infinity();
  double to = std::numeric_limits<double>::infinity();
  bool matches(const std::string& x, const std::string& y, double begin) const;
};

struct ScheduleStep {
  std::string name;                       // named in failures and errors
  std::vector<ScheduleAction> actions;    // at the step's start, in order
  double until = 0.0;                     // s: where the step ends (a wait step's timeout)
  double every = 0.0;                     // s: the checks' pieces (0: the step in one piece)
  std::vector<ScheduleCondition> hold;    // true after every piece
  std::vector<ScheduleCondition> wait;    // all true: the step ends (checked at its start too)
  std::vector<ScheduleCondition> at_end;  // true when the step ends
  std::vector<ScheduleCondition> record;  // recorded when first true at a piece's end
};

struct Schedule {
  std::vector<ScheduleStep> steps;
  bool check_contacts = false;      // the contacts that begin are checked against `allowed`
  std::vector<ContactRule> allowed;
};

// A record condition come true: its step and index in the step's `record`, the time, robot's q and
// the body's pose then (the body's: identity for a condition on holding nothing).
struct ScheduleRecord {
  int step = -1;       // the step's index
  int condition = -1;  // the condition's index in the step's record list
  double t = 0.0;      // s: the end of the piece at which it was first true
  VecN q;              // the robot's joints then (n)
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // the body's pose then (4, 4; identity for nothing)
};

// What a schedule's run did: its steps' times, the groups it added, its records, the contacts it looked
// at, and its failure if it failed.
struct ScheduleOutcome {
  std::vector<std::array<double, 2>> times;  // each step reached: its start and end (s)
  std::vector<int> groups;                   // the group index of each add_cooperative done, in order
  std::vector<ScheduleRecord> records;       // the record conditions come true, in order
  long contacts_seen = 0;                    // the contact events looked at (the next run's `first`)
  // the failure (failed_step -1: none)
  int failed_step = -1;
  std::string kind;       // "contact", "hold", "wait", "at_end", "error"
  int condition = -1;     // hold, wait, at_end: the condition's index in its list
  double t = 0.0;         // s: when (a contact: its begin)
  std::vector<std::string> bodies;  // contact: the two bodies' names
  std::string reason;     // one line
  std::exception_ptr error;  // kind "error": what the engine threw
};

// Checks `schedule` for `sim` without running it: std::invalid_argument naming the step (index and
// name) and the action or condition for a robot or body out of range, a missing controller,
// reference or law, a reference of another dof, a body that is not free, a non-finite wrench, a
// remove without a group, an until before the previous one (or now) or not finite, an every < 0.
void check_schedule(const Simulation& sim, const Schedule& schedule);

// Runs `schedule` on `sim` (checked first), holding the run for its whole length (label "a
// schedule"). contacts_seen: the contact events already looked at (checked from there on).
// between(): called between pieces at most every 4096 steps; throwing stops the run there and
// propagates (a Ctrl-C), the state and log consistent.
ScheduleOutcome run_schedule(Simulation& sim, const Schedule& schedule, long contacts_seen = 0,
                             const std::function<void()>& between = nullptr);

}  // namespace coopsim
