#pragma once
// All agents of a scenario in one process, with exactly the frame semantics of the distributed
// run: in frame k every agent sees the subscribed samples stamped k-1, in canonical order.
// Used by `syndds_sim` (--single-process), RL training, and determinism tests.
#include <atomic>
#include <chrono>
#include <vector>

#include "protocol/agent.hpp"

namespace syndds::proto {

struct LocalRunOptions {
  std::int64_t final_frame = 0;
  double heartbeat_s = 0.01;
  bool realtime = false;
};

/// The frames of a local run one at a time, for callers that act between frames (a learning
/// environment sets the action its controller agent will write, then steps). LocalRunner::run
/// is a loop over it; the frame semantics are the same.
class FrameStepper {
 public:
  FrameStepper(std::vector<AgentPtr> agents, double heartbeat_s);

  /// Runs frame next_frame(): every agent in order, on the samples stamped the frame before
  /// (the wall clock of the run's statistics starts at the first frame).
  /// If an agent fails, every agent is finished (aborted, the last complete frame kept) and the
  /// error is rethrown; the stepper is then finished.
  void step();
  std::int64_t next_frame() const { return completed_ + 1; }
  /// Everything the agents wrote in the last frame, in canonical order.
  const FrameSamples& last_outputs() const { return previous_; }
  /// Ends the run: tells every agent (once) and returns the coordinator's RunControl.
  RunControlMsg finish(RunStatus status, const std::string& reason = "");
  bool finished() const { return finished_; }
  const std::vector<AgentPtr>& agents() const { return agents_; }

 private:
  std::vector<AgentPtr> agents_;
  double heartbeat_s_;
  std::vector<std::vector<Subscription>> subs_;
  std::vector<MemberStatsMsg> member_stats_;
  FrameSamples previous_;  // everything stamped completed_
  std::int64_t completed_ = -1;
  std::chrono::steady_clock::time_point t0_;
  bool finished_ = false;
};

class LocalRunner {
 public:
  LocalRunner(std::vector<AgentPtr> agents, LocalRunOptions options);

  /// Runs frames 0..final_frame (or until `interrupt` becomes true), then tells every agent how
  /// the run ended. Returns the same RunControl the distributed coordinator would send.
  RunControlMsg run(const std::atomic<bool>* interrupt = nullptr);

  const std::vector<AgentPtr>& agents() const { return stepper_.agents(); }

 private:
  FrameStepper stepper_;
  LocalRunOptions options_;
};

/// Throws ProtocolError if a sample in `out` is not stamped (frame, source) as the rules demand
/// or is about another vehicle than the agent's `vehicle_key`.
void check_outputs(const FrameSamples& out, std::int64_t frame, const std::string& source,
                   const std::string& vehicle_key);

}  // namespace syndds::proto
