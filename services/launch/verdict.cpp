#include "launch/verdict.hpp"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace syndds::launch {
namespace fs = std::filesystem;

Verdict verdict(const SupervisorResult& r, const VerdictInput& in) {
  Verdict v;
  const fs::path dir(in.run_dir);
  const std::string logs = (dir / "logs").string();
  std::vector<std::string> notes;
  std::string failed;
  for (const auto& p : r.processes) {
    if (p.status > 0) {
      notes.push_back(describe_exit(p));
      if (failed.empty()) failed = notes.back();
    }
  }
  if (!r.early.empty()) failed = r.early;
  std::string early = r.early;
  if (!early.empty()) {
    const std::string why = last_line(r.early_log);
    if (!why.empty()) early += ": " + why;
  }

  if (!in.decides) {
    // Another host decides the run's verdict; this one reports on its own processes.
    if (r.interrupted) {
      v.exit_code = 130;
    } else if (!r.early.empty()) {
      v.messages.push_back("FAILED: " + early + " (logs: " + logs + ")");
      v.exit_code = 2;
    } else {
      for (const auto& note : notes) v.messages.push_back("note: " + note);
    }
    return v;
  }

  const auto* coordinator = r.find("coordinator");
  const auto* recorder = r.find("recorder");
  const int coordinator_code = coordinator != nullptr ? coordinator->status : -1;
  const int recorder_code = recorder != nullptr ? recorder->status : 0;
  const auto& status = r.status;
  if (!r.interrupted && coordinator_code == 0 && recorder_code == 0) {
    if (fs::exists(dir / "summary.txt")) v.out += read_text((dir / "summary.txt").string());
    for (const auto& p : r.processes) {
      if (p.status <= 0) continue;
      // A member that failed once the run had completed took nothing from the results; the
      // coordinator names it as such (docs/protocol.md, "Failure handling").
      if (status && status->failed_after_end.count(p.name)) {
        v.messages.push_back("note: " + p.name + " failed after the run completed: " +
                             status->failed_after_end.at(p.name) + " (the results are complete)");
      } else {
        v.messages.push_back("note: " + describe_exit(p) +
                             "; the run went on without it (on_member_loss: continue)");
      }
    }
    v.out += "output: " + in.run_dir + "\n";
    if (in.view) v.out += "replay: launch_scripts/view.sh " + in.run_dir + "\n";
    return v;
  }
  if (failed.empty()) failed = "interrupted";

  // One line saying why: who ended the run before it started, an incomplete record, the
  // coordinator's verdict, else who failed first.
  std::string reason;
  if (!r.early.empty()) {
    reason = early;
  } else if (coordinator_code == 0 && recorder_code != 0) {
    reason = "the run completed but the recording is incomplete: " + describe_exit(*recorder);
    try {
      const auto j = nlohmann::json::parse(read_text((dir / "summary.json").string()));
      if (j.contains("recorded_up_to_frame")) {
        reason += " (frames 0 to " + std::to_string(j.at("recorded_up_to_frame").get<long long>()) +
                  " are in " + in.run_dir + ")";
      }
    } catch (const std::exception&) {
    }
  } else if (status && status->ended() && status->state != "completed") {
    reason = "run '" + status->scenario + "' aborted" +
             (status->reason.empty() ? "" : ": " + status->reason);
  }
  if (reason.empty()) reason = failed;
  if (r.interrupted) {
    v.messages.push_back("interrupted: " + reason + " (logs: " + logs + ")");
    v.exit_code = 130;
    return v;
  }
  v.messages.push_back("FAILED: " + reason + " [first exit: " + failed + "] (logs: " + logs + ")");
  v.exit_code = 2;
  return v;
}

}  // namespace syndds::launch
