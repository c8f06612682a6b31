#pragma once
// Multi-process test helpers: start the real programs (each with its own log file), wait for
// conditions with bounded retries, never bare sleeps. Every test gets its own DDS domain and
// run id, and CTest runs each test in a private network namespace (tests/netns_exec.sh).
#include <gtest/gtest.h>
#include <signal.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace syndds::test {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

inline const std::string kBin = SYNDDS_BIN_DIR;
inline const std::string kSource = SYNDDS_SOURCE_DIR;
inline const std::string kConfig = kSource + "/config";

inline std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

inline std::size_t count_lines(const std::string& text) {
  return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
}

/// Fields of one CSV line.
inline std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string x; std::getline(ss, x, ',');) out.push_back(x);
  return out;
}

/// Polls `condition` every 20 ms until it holds or `timeout_s` passes.
inline bool wait_until(const std::function<bool()>& condition, double timeout_s) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (!condition()) {
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

/// A child process running `/bin/sh -c "exec COMMAND"` with stdout+stderr to `log`.
class Process {
 public:
  Process(const std::string& command, const fs::path& log) : log_(log) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    const std::string script = "exec " + command;
    const char* argv[] = {"/bin/sh", "-c", script.c_str(), nullptr};
    const int rc = posix_spawn(&pid_, "/bin/sh", &actions, nullptr,
                               const_cast<char* const*>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (rc != 0) throw std::runtime_error("cannot start: " + command);
  }
  ~Process() {
    if (!code_) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  const fs::path& log_file() const { return log_; }
  std::string log() const { return read_file(log_); }
  void signal(int sig) { ::kill(pid_, sig); }

  /// Exit status (128 + signal when killed by one), or nullopt if still running.
  std::optional<int> poll() {
    if (code_) return code_;
    int status = 0;
    if (waitpid(pid_, &status, WNOHANG) == pid_) {
      code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    }
    return code_;
  }
  /// Waits up to `timeout_s` for the exit; nullopt if it is still running then.
  std::optional<int> wait(double timeout_s) {
    wait_until([&] { return poll().has_value(); }, timeout_s);
    return code_;
  }

 private:
  pid_t pid_ = 0;
  fs::path log_;
  std::optional<int> code_;
};

/// A fresh folder, DDS domain and run id for the current test.
struct TestRun {
  fs::path dir;
  int domain = 0;
  std::string run_id;

  TestRun() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = std::string(info->test_suite_name()) + "." + info->name();
    dir = fs::path(testing::TempDir()) / ("syndds-" + name + "-" + std::to_string(getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    // Distinct domains also when network namespaces are unavailable.
    domain = 20 + static_cast<int>(std::hash<std::string>{}(name) % 180);
    run_id = "test-" + std::to_string(getpid()) + "-" + info->name();
  }
  ~TestRun() {
    // Keep the logs of a failed test for inspection; remove the rest.
    if (!testing::Test::HasFailure()) {
      std::error_code ec;
      fs::remove_all(dir, ec);
    }
  }
  TestRun(const TestRun&) = delete;
  TestRun& operator=(const TestRun&) = delete;

  /// Arguments every process of this run gets.
  std::string common_args() const {
    return " --domain " + std::to_string(domain) + " --run-id " + run_id;
  }
};

/// One process of a planned run: its member id and command line.
struct Planned {
  std::string member;
  std::string command;
};

/// Asks syndds_plan for the processes of `scenario` (extra: more options, e.g. --duration).
inline std::vector<Planned> plan(const TestRun& run, const std::string& scenario,
                                 const std::string& output, const std::string& extra) {
  const fs::path out = run.dir / "plan.txt";
  const std::string cmd = kBin + "/syndds_plan " + scenario + " --format launcher --output " +
                          output + run.common_args() + " " + extra + " > " + out.string();
  if (std::system(cmd.c_str()) != 0) throw std::runtime_error("syndds_plan failed: " + cmd);
  std::vector<Planned> out_list;
  std::istringstream in(read_file(out));
  std::string line;
  while (std::getline(in, line)) {
    const auto tab = line.find('\t');
    if (tab == std::string::npos) continue;
    out_list.push_back({line.substr(0, tab), line.substr(tab + 1)});
  }
  return out_list;
}

/// A copy of `scenario` in `dir` with soil routing on (docs/scm.md, "Routing"); its terrain
/// block must have the line "  spacing_m: 0.05".
inline std::string routed_copy(const std::string& scenario, const fs::path& dir) {
  std::string text = read_file(scenario);
  const std::string anchor = "  spacing_m: 0.05\n";
  const auto at = text.find(anchor);
  if (at == std::string::npos) throw std::runtime_error(scenario + ": no '  spacing_m: 0.05' line");
  text.replace(at, anchor.size(), anchor + "  routing: true\n");
  const fs::path copy = dir / ("routed_" + fs::path(scenario).filename().string());
  std::ofstream(copy) << text;
  return copy.string();
}

inline std::string log_name(const std::string& member) {
  std::string s = member;
  for (char& c : s) {
    if (c == '/') c = '_';
  }
  return s + ".log";
}

/// The launcher's OUTPUT/logs/pids: member id and process id of everything it started.
inline std::vector<std::pair<std::string, int>> launched_pids(const fs::path& output) {
  std::vector<std::pair<std::string, int>> out;
  std::istringstream in(read_file(output / "logs" / "pids"));
  std::string member;
  int pid = 0;
  while (in >> member >> pid) out.emplace_back(member, pid);
  return out;
}

/// The pid the launcher recorded for `member` (0 if none).
inline int launched_pid(const fs::path& output, const std::string& member) {
  for (const auto& [m, pid] : launched_pids(output)) {
    if (m == member) return pid;
  }
  return 0;
}

/// A launcher run of `scenario` in the background (its output in run.dir / "out").
inline std::unique_ptr<Process> start_launcher(const TestRun& run, const std::string& scenario,
                                               const std::string& extra = "") {
  // The launcher runs the programs of the build under test, wherever that build is.
  return std::make_unique<Process>("env SYNDDS_BUILD_DIR=" + kBin + "/.. " + kSource +
                                       "/launch_scripts/run_scenario.sh " + scenario +
                                       " --output " + (run.dir / "out").string() +
                                       run.common_args() + " " + extra,
                                   run.dir / "launcher.log");
}

/// Starts planned processes in the given order; `tweak` may change a member's command.
inline std::vector<std::unique_ptr<Process>> start_all(
    const TestRun& run, std::vector<Planned> processes,
    const std::function<std::string(const Planned&)>& tweak = {}) {
  std::vector<std::unique_ptr<Process>> out;
  for (const auto& p : processes) {
    const std::string cmd = tweak ? tweak(p) : p.command;
    out.push_back(std::make_unique<Process>(cmd, run.dir / log_name(p.member)));
  }
  return out;
}

/// Waits for every process; returns their exit codes (-1 for one still running at the end).
inline std::vector<int> wait_all(std::vector<std::unique_ptr<Process>>& procs, double timeout_s) {
  std::vector<int> codes;
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  for (auto& p : procs) {
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    auto c = p->wait(std::max(0.0, left));
    codes.push_back(c ? *c : -1);
  }
  return codes;
}

inline std::string describe_logs(const std::vector<std::unique_ptr<Process>>& procs) {
  std::string out;
  for (const auto& p : procs) out += "---- " + p->log_file().string() + "\n" + p->log();
  return out;
}

/// Runs `syndds_sim` (all agents in one process) and returns its vehicles.csv.
inline std::string single_process_csv(const TestRun& run, const std::string& scenario,
                                      const std::string& extra) {
  const fs::path out = run.dir / "single";
  const std::string cmd = kBin + "/syndds_sim " + scenario + " --quiet --output " + out.string() +
                          " " + extra + " > " + (run.dir / "single.log").string() + " 2>&1";
  if (std::system(cmd.c_str()) != 0) {
    throw std::runtime_error("syndds_sim failed: " + read_file(run.dir / "single.log"));
  }
  return read_file(out / "vehicles.csv");
}

}  // namespace syndds::test
