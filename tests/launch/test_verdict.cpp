#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>

#include "launch/verdict.hpp"

namespace fs = std::filesystem;
using namespace syndds::launch;

namespace {

struct Outcome {
  fs::path dir;
  SupervisorResult r;
  explicit Outcome(const char* name) {
    dir = fs::temp_directory_path() / ("syndds-verdict-" + std::to_string(::getpid()) + "-" + name);
    fs::remove_all(dir);
    fs::create_directories(dir / "logs");
  }
  ~Outcome() { fs::remove_all(dir); }
  void add(const std::string& name, int status, bool signaled = false) {
    ProcessOutcome p;
    p.name = name;
    p.status = status;
    p.signaled = signaled;
    std::string file = name;
    for (char& c : file) c = c == '/' ? '_' : c;
    p.log = (dir / "logs" / (file + ".log")).string();
    r.processes.push_back(p);
  }
  Verdict decide(bool decides = true) { return verdict(r, {dir.string(), decides, false}); }
};

}  // namespace

TEST(Verdict, ACompletedRunPrintsItsSummaryAndNotes) {
  Outcome run("completed");
  std::ofstream(run.dir / "summary.txt") << "run 'x' completed\n";
  run.add("coordinator", 0);
  run.add("vehicle/b", 128 + SIGKILL, true);
  run.add("sensor/a", 3);
  run.add("recorder", 0);
  RunStatus s;
  s.state = "completed";
  s.failed_after_end["sensor/a"] = "its finish() threw";
  run.r.status = s;
  const auto v = run.decide();
  EXPECT_EQ(v.exit_code, 0);
  EXPECT_EQ(v.out, "run 'x' completed\noutput: " + run.dir.string() + "\n");
  ASSERT_EQ(v.messages.size(), 2u);
  EXPECT_EQ(v.messages[0],
            "note: vehicle/b was killed by signal 9; the run went on without it "
            "(on_member_loss: continue)");
  EXPECT_EQ(v.messages[1],
            "note: sensor/a failed after the run completed: its finish() threw (the results "
            "are complete)");
}

TEST(Verdict, AMemberThatNeverJoinedIsNamedWithItsLastLogLine) {
  Outcome run("early");
  run.add("coordinator", 128 + SIGTERM, true);
  run.add("vehicle/a", 3);
  std::ofstream(run.r.processes[1].log) << "starting\nerror: this vehicle cannot start\n\n";
  run.r.early = "vehicle/a exited (status 3) before the run started";
  run.r.early_log = run.r.processes[1].log;
  const auto v = run.decide();
  EXPECT_EQ(v.exit_code, 2);
  ASSERT_EQ(v.messages.size(), 1u);
  EXPECT_EQ(v.messages[0],
            "FAILED: vehicle/a exited (status 3) before the run started: error: this vehicle "
            "cannot start [first exit: vehicle/a exited (status 3) before the run started] "
            "(logs: " +
                (run.dir / "logs").string() + ")");
  // On a host that does not decide, the same failure is its own exit status and line.
  const auto other = run.decide(false);
  EXPECT_EQ(other.exit_code, 2);
  ASSERT_EQ(other.messages.size(), 1u);
  EXPECT_EQ(other.messages[0].rfind("FAILED: vehicle/a exited (status 3) before the run started: "
                                    "error: this vehicle cannot start",
                                    0),
            0u);
}

TEST(Verdict, AnAbortedRunGivesTheCoordinatorsReason) {
  Outcome run("aborted");
  run.add("coordinator", 2);
  run.add("vehicle/b", 128 + SIGKILL, true);
  RunStatus s;
  s.scenario = "long_run";
  s.state = "aborted";
  s.reason = "member vehicle/b lost: its process exited";
  run.r.status = s;
  const auto v = run.decide();
  EXPECT_EQ(v.exit_code, 2);
  ASSERT_EQ(v.messages.size(), 1u);
  EXPECT_EQ(v.messages[0].rfind("FAILED: run 'long_run' aborted: member vehicle/b lost: its "
                                "process exited [first exit: coordinator exited with status 2]",
                                0),
            0u)
      << v.messages[0];
}

TEST(Verdict, AMissingRecordingIsReportedWithWhatWasKept) {
  Outcome run("recorder");
  run.add("coordinator", 0);
  run.add("recorder", 128 + SIGKILL, true);
  std::ofstream(run.dir / "summary.json") << R"({"status": "running", "recorded_up_to_frame": 41})";
  const auto v = run.decide();
  EXPECT_EQ(v.exit_code, 2);
  ASSERT_EQ(v.messages.size(), 1u);
  EXPECT_NE(v.messages[0].find("the run completed but the recording is incomplete: recorder was "
                               "killed by signal 9 (frames 0 to 41 are in " +
                               run.dir.string() + ")"),
            std::string::npos)
      << v.messages[0];
}

TEST(Verdict, AnInterruptedRunSaysSo) {
  Outcome run("interrupted");
  run.add("coordinator", 130);
  run.add("vehicle/a", 130);
  run.r.interrupted = true;
  const auto v = run.decide();
  EXPECT_EQ(v.exit_code, 130);
  ASSERT_EQ(v.messages.size(), 1u);
  EXPECT_EQ(v.messages[0].rfind("interrupted: coordinator was interrupted", 0), 0u)
      << v.messages[0];
  EXPECT_EQ(run.decide(false).exit_code, 130);
}
