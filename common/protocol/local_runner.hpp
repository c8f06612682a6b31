#pragma once
// All agents of a scenario in one process, with exactly the frame semantics of the distributed
// run: in frame k every agent sees the subscribed samples stamped k-1, in canonical order.
// Used by `syndds_sim` (--single-process), RL training, and determinism tests.
#include <atomic>
#include <vector>

#include "protocol/agent.hpp"

namespace syndds::proto {

struct LocalRunOptions {
  std::int64_t final_frame = 0;
  double heartbeat_s = 0.01;
  bool realtime = false;
};

class LocalRunner {
 public:
  LocalRunner(std::vector<AgentPtr> agents, LocalRunOptions options);

  /// Runs frames 0..final_frame (or until `interrupt` becomes true), then tells every agent how
  /// the run ended. Returns the same RunControl the distributed coordinator would send.
  RunControlMsg run(const std::atomic<bool>* interrupt = nullptr);

  const std::vector<AgentPtr>& agents() const { return agents_; }

 private:
  std::vector<AgentPtr> agents_;
  LocalRunOptions options_;
};

/// Throws ProtocolError if a sample in `out` is not stamped (frame, source) as the rules demand
/// or is about another vehicle than the agent's `vehicle_key`.
void check_outputs(const FrameSamples& out, std::int64_t frame, const std::string& source,
                   const std::string& vehicle_key);

}  // namespace syndds::proto
