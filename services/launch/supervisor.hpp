#pragma once
// Starts the processes of a run on this host and watches them until the run has ended
// (docs/deployment.md, "The launcher"). Linux only: processes are started with posix_spawn and
// watched through pidfds, the run's state comes from the coordinator's status file (watched
// with inotify), signals arrive through a signalfd; one thread, one epoll loop, no polling of
// processes. Nothing here reads a log to decide anything.
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace syndds::launch {

/// The coordinator's status file (CoordinatorOptions::status_file), as read.
struct RunStatus {
  std::string run_id;
  std::string scenario;
  long pid = 0;
  std::string state;  // joining, running, completed, aborted, interrupted
  long long frame = -1;
  long long recoveries = 0;
  std::string reason;
  int exit_code = -1;
  std::map<std::string, std::string> failed_after_end;
  bool final = false;

  bool started() const { return !state.empty() && state != "joining"; }
  bool ended() const {
    return state == "completed" || state == "aborted" || state == "interrupted";
  }
};
/// Parses a status file; nullopt if it is missing, partial or not one.
std::optional<RunStatus> read_run_status(const std::string& path);

struct SupervisedProcess {
  std::string name;               // as planned: coordinator, vehicle/a, recorder, group/a, ...
  std::vector<std::string> argv;  // argv[0] is a path
  std::string log;                // stdout and stderr go here (created, truncated)
};

struct SupervisorConfig {
  /// In start order. When the coordinator is among them it comes first: starting stops as soon
  /// as it has exited (nothing started after the end can take part).
  std::vector<SupervisedProcess> processes;
  /// The coordinator's status file (its run directory's run_status.json).
  std::string status_file;
  /// The file system of status_file may not report changes made on other hosts (NFS): read it
  /// again every second besides inotify's events. For hosts without the coordinator.
  bool status_remote = false;
  /// on_member_loss: recover: a process killed by a signal (other than SIGINT) while the run
  /// goes on is started again with --rejoin, at most max_restarts times.
  bool recover = false;
  int max_restarts = 0;
  /// After the run has ended (the coordinator exited, or on a host without it the status says
  /// so): time for the rest to exit before they are sent TERM, then stop_s more before KILL.
  double grace_s = 20.0;
  double stop_s = 5.0;
  /// Each started process appends "NAME PID" (or "NAME HOST PID" when host is set) here.
  std::string pids_file;
  std::string host;
  /// Messages for the user (one line each, no trailing newline).
  std::function<void(const std::string&)> say;
};

struct ProcessOutcome {
  std::string name;
  /// Exit status as a shell gives it: the exit code, or 128 + the signal; -1 if never started.
  int status = -1;
  bool signaled = false;
  int restarts = 0;
  std::string log;  // the log of its last start
};

struct SupervisorResult {
  std::vector<ProcessOutcome> processes;
  bool interrupted = false;  // SIGINT, SIGTERM or SIGHUP reached the launcher
  /// "X exited (status N) before the run started", and X's log, when that ended the run.
  std::string early;
  std::string early_log;
  std::optional<RunStatus> status;  // the newest the coordinator wrote
  /// The processes that were still running when the launcher had to stop them.
  bool stopped_any = false;

  const ProcessOutcome* find(const std::string& name) const;
};

class Supervisor {
 public:
  explicit Supervisor(SupervisorConfig config);
  /// Runs until every started process has exited; SIGINT, SIGTERM and SIGHUP are handled here
  /// (they stop the run) while it runs and restored after.
  SupervisorResult run();

 private:
  SupervisorConfig config_;
};

/// "killed by signal 9", "was interrupted", "exited with status 3".
std::string describe_exit(const ProcessOutcome& p);
/// A file's whole text ("" if it cannot be read).
std::string read_text(const std::string& path);
/// The last non-empty line of a text file ("" if none).
std::string last_line(const std::string& path);

}  // namespace syndds::launch
