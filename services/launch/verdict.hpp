#pragma once
// What a launcher says when its processes have ended, and its exit status (docs/deployment.md,
// "The launcher"): the run's summary and notes when it completed, else one line saying why.
#include <string>
#include <vector>

#include "launch/supervisor.hpp"

namespace syndds::launch {

struct VerdictInput {
  std::string run_dir;  // as the user named it (messages), e.g. runs/default-...
  bool decides = true;  // this host runs the coordinator: the run's verdict is its to give
  bool view = false;    // the run had a viewer: say how to replay it
};

struct Verdict {
  int exit_code = 0;                  // 0 completed, 2 failed, 130 interrupted
  std::string out;                    // for standard output: the summary, "output: DIR", ...
  std::vector<std::string> messages;  // for standard error, one line each (no prefix)
};

/// Reads RUN_DIR/summary.txt (a completed run's summary), RUN_DIR/summary.json
/// (recorded_up_to_frame) and the early-exit member's log (its last line); never decides on
/// log text.
Verdict verdict(const SupervisorResult& r, const VerdictInput& in);

}  // namespace syndds::launch
