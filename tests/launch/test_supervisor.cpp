// The supervisor with shell scripts for the run's processes: a fake coordinator writes the
// status file as the real one does (whole, then renamed into place).
#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "launch/supervisor.hpp"

namespace fs = std::filesystem;
using namespace syndds::launch;

namespace {

struct Dir {
  fs::path path;
  Dir() {
    path = fs::temp_directory_path() /
           ("syndds-supervisor-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path);
    fs::create_directories(path / "logs");
  }
  ~Dir() { fs::remove_all(path); }
  std::string status() const { return (path / "logs" / "run_status.json").string(); }
};

// A shell command writing the status file with `state`.
std::string write_status(const Dir& d, const std::string& state, const std::string& extra = "") {
  return "printf '{\"run_id\": \"r\", \"scenario\": \"s\", \"state\": \"" + state + "\"" + extra +
         "}' > " + d.status() + ".tmp && mv " + d.status() + ".tmp " + d.status();
}

SupervisedProcess sh(const Dir& d, const std::string& name, const std::string& script) {
  std::string file = name;
  for (char& c : file) c = c == '/' ? '_' : c;
  return {name, {"/bin/sh", "-c", script, name}, (d.path / "logs" / (file + ".log")).string()};
}

SupervisorConfig config(const Dir& d, std::vector<SupervisedProcess> processes) {
  SupervisorConfig c;
  c.processes = std::move(processes);
  c.status_file = d.status();
  c.grace_s = 5.0;
  c.stop_s = 2.0;
  c.pids_file = (d.path / "logs" / "pids").string();
  return c;
}

std::string read(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

TEST(Supervisor, ACompletedRunEndsWithEveryStatus) {
  Dir d;
  // The member waits for the status to say completed: it learns the end from the file too.
  const std::string wait_end = "for i in $(seq 200); do grep -q completed " + d.status() +
                               " 2>/dev/null && exit 0; sleep 0.05; done; exit 9";
  auto c = config(d, {sh(d, "coordinator",
                         write_status(d, "running") + " && sleep 0.3 && " +
                             write_status(d, "completed", ", \"final\": true")),
                      sh(d, "vehicle/a", wait_end)});
  const auto r = Supervisor(c).run();
  ASSERT_EQ(r.processes.size(), 2u);
  EXPECT_EQ(r.processes[0].status, 0);
  EXPECT_EQ(r.processes[1].status, 0);
  EXPECT_TRUE(r.early.empty()) << r.early;
  EXPECT_FALSE(r.stopped_any);
  EXPECT_FALSE(r.interrupted);
  ASSERT_TRUE(r.status.has_value());
  EXPECT_EQ(r.status->state, "completed");
  EXPECT_TRUE(r.status->final);
  // Every start is in the pids file.
  const std::string pids = read(d.path / "logs" / "pids");
  EXPECT_NE(pids.find("coordinator "), std::string::npos) << pids;
  EXPECT_NE(pids.find("vehicle/a "), std::string::npos) << pids;
}

TEST(Supervisor, AMemberEndingBeforeTheRunStartedStopsTheRest) {
  Dir d;
  auto c = config(d, {sh(d, "coordinator", write_status(d, "joining") + " && exec sleep 60"),
                      sh(d, "vehicle/a", "sleep 0.3; echo 'error: cannot start' >&2; exit 3"),
                      sh(d, "controller/a", "exec sleep 60")});
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = Supervisor(c).run();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20));
  EXPECT_EQ(r.early, "vehicle/a exited (status 3) before the run started");
  EXPECT_EQ(last_line(r.early_log), "error: cannot start");
  EXPECT_TRUE(r.stopped_any);
  EXPECT_EQ(r.processes[0].status, 128 + SIGTERM);
  EXPECT_EQ(r.processes[2].status, 128 + SIGTERM);
}

TEST(Supervisor, AMemberKilledWhileTheRunGoesOnIsRestartedUnderRecover) {
  Dir d;
  // The first start kills itself; the restart (given --rejoin) waits for the end.
  const std::string member =
      "case \" $* \" in *' --rejoin '*) "
      "for i in $(seq 200); do grep -q completed " +
      d.status() +
      " && exit 0; sleep 0.05; done; "
      "exit 9;; esac; until grep -q running " +
      d.status() +
      " 2>/dev/null; do sleep 0.05; done; "
      "kill -KILL $$";
  // The coordinator learns of the restart as the real one does not, from the pids file (a
  // second vehicle/a line), and then completes the run.
  const std::string pids = (d.path / "logs" / "pids").string();
  auto c = config(d, {sh(d, "coordinator",
                         write_status(d, "running") + " && while [ $(grep -c vehicle/a " + pids +
                             ") -lt 2 ]; do sleep 0.05; done; sleep 0.2; " +
                             write_status(d, "completed", ", \"final\": true")),
                      sh(d, "vehicle/a", member)});
  c.recover = true;
  c.max_restarts = 2;
  std::vector<std::string> said;
  c.say = [&](const std::string& s) { said.push_back(s); };
  const auto r = Supervisor(c).run();
  EXPECT_EQ(r.processes[0].status, 0);
  EXPECT_EQ(r.processes[1].status, 0);
  EXPECT_EQ(r.processes[1].restarts, 1);
  EXPECT_TRUE(fs::exists(d.path / "logs" / "vehicle_a.restart1.log"));
  ASSERT_FALSE(said.empty());
  EXPECT_EQ(said.front(), "vehicle/a was killed by signal 9; restarting it (1 of at most 2)");
  EXPECT_TRUE(r.early.empty());
}

TEST(Supervisor, WithoutRecoverAKilledMemberStaysDead) {
  Dir d;
  auto c = config(d, {sh(d, "coordinator",
                         write_status(d, "running") + " && sleep 1 && " +
                             write_status(d, "aborted", ", \"reason\": \"lost\"")),
                      sh(d, "vehicle/a",
                         "until grep -q running " + d.status() +
                             " 2>/dev/null; do sleep 0.05; done; kill -KILL $$")});
  const auto r = Supervisor(c).run();
  EXPECT_EQ(r.processes[1].status, 128 + SIGKILL);
  EXPECT_TRUE(r.processes[1].signaled);
  EXPECT_EQ(r.processes[1].restarts, 0);
  EXPECT_EQ(describe_exit(r.processes[1]), "vehicle/a was killed by signal 9");
  EXPECT_EQ(r.status->reason, "lost");
}

TEST(Supervisor, ProcessesOutlivingTheRunAreStoppedAfterTheGrace) {
  Dir d;
  auto c = config(
      d, {sh(d, "coordinator",
             write_status(d, "running") + " && sleep 0.2 && " + write_status(d, "completed")),
          sh(d, "vehicle/a", "trap '' TERM; exec sleep 60")});
  c.grace_s = 0.3;
  c.stop_s = 0.3;
  std::vector<std::string> said;
  c.say = [&](const std::string& s) { said.push_back(s); };
  const auto r = Supervisor(c).run();
  EXPECT_TRUE(r.stopped_any);
  // The member ignores TERM (an ignored signal stays ignored across exec): only the KILL
  // stop_s after the TERM ends it.
  EXPECT_EQ(r.processes[1].status, 128 + SIGKILL);
  ASSERT_FALSE(said.empty());
  EXPECT_EQ(said.front(), "processes still running after the end of the run; stopping them");
}

TEST(Supervisor, AHostWithoutTheCoordinatorFollowsTheStatusFile) {
  Dir d;
  // Another host's coordinator: the status file is written from outside this supervisor.
  auto c = config(d, {sh(d, "vehicle/b", "exec sleep 60"),
                      sh(d, "writer",
                         write_status(d, "running") + " && sleep 0.3 && " +
                             write_status(d, "completed") + "; exec sleep 60")});
  c.status_remote = true;
  c.grace_s = 0.2;
  const auto r = Supervisor(c).run();
  EXPECT_TRUE(r.early.empty());
  EXPECT_EQ(r.processes[0].status, 128 + SIGTERM);
  EXPECT_EQ(r.status->state, "completed");
}

TEST(Supervisor, ASignalToTheLauncherStopsEveryProcess) {
  Dir d;
  // The member sends TERM to its parent, the supervisor, as Ctrl-C or scancel would.
  auto c = config(d, {sh(d, "coordinator", write_status(d, "running") + " && exec sleep 60"),
                      sh(d, "vehicle/a", "sleep 0.2; kill -TERM $PPID; exec sleep 60")});
  const auto r = Supervisor(c).run();
  EXPECT_TRUE(r.interrupted);
  EXPECT_EQ(r.processes[0].status, 128 + SIGTERM);
  EXPECT_EQ(r.processes[1].status, 128 + SIGTERM);
  // The launcher's signals are its own again afterwards.
  sigset_t mask;
  sigprocmask(SIG_SETMASK, nullptr, &mask);
  EXPECT_FALSE(sigismember(&mask, SIGTERM));
}

// A launcher started with SIGINT ignored (a background job of a non-interactive shell) still
// hears Ctrl-C, and leaves the disposition as it found it.
TEST(Supervisor, AnIgnoredInterruptStillReachesTheLauncher) {
  Dir d;
  struct sigaction ignore {
  }, before{};
  ignore.sa_handler = SIG_IGN;
  sigaction(SIGINT, &ignore, &before);
  auto c = config(d, {sh(d, "coordinator", write_status(d, "running") + " && exec sleep 60"),
                      sh(d, "vehicle/a", "sleep 0.2; kill -INT $PPID; exec sleep 60")});
  const auto r = Supervisor(c).run();
  struct sigaction after {};
  sigaction(SIGINT, &before, &after);
  EXPECT_TRUE(r.interrupted);
  EXPECT_EQ(r.processes[0].status, 128 + SIGTERM);
  EXPECT_EQ(after.sa_handler, SIG_IGN);
}

TEST(Supervisor, AProgramThatCannotStartIsReportedAs127) {
  Dir d;
  auto c = config(d, {{"coordinator",
                       {"/nonexistent/syndds_coordinator"},
                       (d.path / "logs" / "coordinator.log").string()}});
  const auto r = Supervisor(c).run();
  EXPECT_EQ(r.processes[0].status, 127);
  EXPECT_NE(read(d.path / "logs" / "coordinator.log").find("cannot start"), std::string::npos);
}

// Once a member's early exit stopped every process, nothing more is started: a process started
// after that would be stopped only at the next level, stop_s later (here 60 s). Vehicle/a exits
// at once, while 40 controllers are still to be started one a turn.
TEST(Supervisor, NothingStartsAfterAnEarlyExitStoppedTheRest) {
  Dir d;
  std::vector<SupervisedProcess> processes{
      sh(d, "coordinator", write_status(d, "joining") + " && exec sleep 120"),
      sh(d, "vehicle/a", "exit 3")};
  for (int i = 0; i < 40; ++i) {
    processes.push_back(sh(d, "controller/" + std::to_string(i), "exec sleep 120"));
  }
  auto c = config(d, std::move(processes));
  c.stop_s = 60.0;
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = Supervisor(c).run();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(30));
  EXPECT_EQ(r.early, "vehicle/a exited (status 3) before the run started");
  EXPECT_EQ(r.processes[0].status, 128 + SIGTERM);
}

TEST(Supervisor, AMemberThatCannotStartEndsTheRunBeforeItStarted) {
  Dir d;
  auto c = config(d, {sh(d, "coordinator", write_status(d, "joining") + " && exec sleep 60"),
                      {"vehicle/a",
                       {"/nonexistent/syndds_vehicle"},
                       (d.path / "logs" / "vehicle_a.log").string()}});
  const auto r = Supervisor(c).run();
  EXPECT_EQ(r.processes[1].status, 127);
  EXPECT_EQ(r.early, "vehicle/a exited (status 127) before the run started");
  EXPECT_EQ(r.processes[0].status, 128 + SIGTERM);
}

TEST(Supervisor, StatusFilesThatAreNotOneAreIgnored) {
  Dir d;
  std::ofstream(d.status()) << "{\"state\": \"runn";
  EXPECT_FALSE(read_run_status(d.status()).has_value());
  std::ofstream(d.status()) << R"({"state": "completed", "failed_after_end": {"sensor/a": "x"}})";
  const auto s = read_run_status(d.status());
  ASSERT_TRUE(s.has_value());
  EXPECT_TRUE(s->ended());
  EXPECT_TRUE(s->started());
  EXPECT_EQ(s->failed_after_end.at("sensor/a"), "x");
}
