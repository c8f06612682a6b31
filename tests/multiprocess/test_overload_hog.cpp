// Overload is not death (issue 14): the default scenario, run distributed beside CPU hogs that
// keep the load at ten times the core count, completes and equals the undisturbed single-process
// run. Its own executable so that CTest runs it alone (RUN_SERIAL): the hogs would otherwise
// slow every test running beside it.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "harness.hpp"

using namespace syndds::test;

namespace {

// `count` child processes spinning at full speed, killed when this goes out of scope.
class CpuHogs {
 public:
  explicit CpuHogs(unsigned count) {
    for (unsigned k = 0; k < count; ++k) {
      const pid_t pid = ::fork();
      if (pid == 0) {
        volatile unsigned long spin = 0;
        for (;;) spin = spin + 1;
      }
      if (pid > 0) pids_.push_back(pid);
    }
  }
  ~CpuHogs() {
    for (const pid_t pid : pids_) ::kill(pid, SIGKILL);
    for (const pid_t pid : pids_) ::waitpid(pid, nullptr, 0);
  }
  CpuHogs(const CpuHogs&) = delete;
  CpuHogs& operator=(const CpuHogs&) = delete;
  std::size_t size() const { return pids_.size(); }

 private:
  std::vector<pid_t> pids_;
};

}  // namespace

TEST(Overload, DefaultRunBesideCpuHogsIsUnchanged) {
  TestRun run;
  const fs::path out = run.dir / "out";
  const std::string scenario = kConfig + "/scenarios/default.yaml";
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  std::optional<int> code;
  std::string load, log;
  {
    CpuHogs hogs(10 * cores);
    ASSERT_EQ(hogs.size(), 10 * cores);
    auto launcher = start_launcher(run, scenario, "--duration 10");
    // Bounded generously: at load 20 on 2 cores each process gets a fraction of a core.
    code = launcher->wait(400);
    load = read_file("/proc/loadavg");
    log = launcher->log();
  }  // the hogs end here
  ASSERT_TRUE(code.has_value()) << "still running; load " << load << log;
  EXPECT_EQ(*code, 0) << "load " << load << log << read_file(out / "logs" / "coordinator.log");
  EXPECT_EQ(read_file(out / "vehicles.csv"), single_process_csv(run, scenario, "--duration 10"));
}
