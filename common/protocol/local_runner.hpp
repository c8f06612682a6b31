#pragma once
// All agents of a scenario in one process, with exactly the frame semantics of the distributed
// run: in frame k every agent sees the subscribed samples stamped k-1, in canonical order.
// Used by `syndds_sim` (--single-process), RL training, and determinism tests.
#include <atomic>
#include <chrono>
#include <functional>
#include <vector>

#include "protocol/agent.hpp"

namespace syndds::proto {

class FrameStepper;

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
  /// The samples agent `i` steps the next frame with.
  FrameSamples next_inputs(std::size_t i) const;
  /// Continues a run from a checkpoint: frame `completed_frame` is taken as done and agent i
  /// steps the next frame with `next_inputs[i]` (the agents' states were restored by the
  /// caller). Only before the first step.
  void resume(std::int64_t completed_frame, std::vector<FrameSamples> next_inputs);
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
  std::vector<FrameSamples> resumed_inputs_;  // per agent, for the first frame after resume()
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
  /// The stepper, e.g. to resume() before run().
  FrameStepper& stepper() { return stepper_; }
  /// Called after every frame (e.g. to write a checkpoint when one is due).
  void set_after_frame(std::function<void(FrameStepper&)> f) { after_frame_ = std::move(f); }

 private:
  FrameStepper stepper_;
  LocalRunOptions options_;
  std::function<void(FrameStepper&)> after_frame_;
};

/// Throws ProtocolError if a sample in `out` is not stamped (frame, source) as the rules demand
/// or is about another vehicle than the agent's `vehicle_key`.
void check_outputs(const FrameSamples& out, std::int64_t frame, const std::string& source,
                   const std::string& vehicle_key);

}  // namespace syndds::proto
