#include "launch/supervisor.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/epoll.h>
#include <sys/inotify.h>
#include <sys/signalfd.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

extern char** environ;

namespace syndds::launch {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

[[noreturn]] void fail(const std::string& what) {
  throw std::runtime_error(what + ": " + std::strerror(errno));
}

int pidfd_open(pid_t pid) { return static_cast<int>(::syscall(SYS_pidfd_open, pid, 0)); }

// epoll tags: processes are their index; these are above any index.
constexpr std::uint64_t kSignalTag = 1ull << 62;
constexpr std::uint64_t kInotifyTag = kSignalTag + 1;

struct Child {
  pid_t pid = -1;
  int pidfd = -1;
  bool running = false;
};

class Loop {
 public:
  explicit Loop(SupervisorConfig& config) : c_(config) {
    result_.processes.resize(c_.processes.size());
    children_.resize(c_.processes.size());
    for (std::size_t i = 0; i < c_.processes.size(); ++i) {
      result_.processes[i].name = c_.processes[i].name;
    }
  }

  ~Loop() {
    for (auto& ch : children_) {
      if (ch.pidfd >= 0) ::close(ch.pidfd);
    }
    if (inotify_ >= 0) ::close(inotify_);
    if (signal_fd_ >= 0) ::close(signal_fd_);
    if (epoll_ >= 0) ::close(epoll_);
    if (signals_blocked_) {
      ::sigprocmask(SIG_SETMASK, &old_mask_, nullptr);
      for (std::size_t k = 0; k < kSignals.size(); ++k) {
        ::sigaction(kSignals[k], &old_actions_[k], nullptr);
      }
    }
  }

  SupervisorResult run() {
    setup();
    std::size_t next = 0;
    bool stopped_starting = false;
    read_status();
    while (true) {
      // Start one process a turn, so that events (the coordinator's exit, a signal) are seen
      // between two starts: with hundreds of processes starting takes long.
      if (next < c_.processes.size() && !stopped_starting) {
        // Nor once every process was told to stop (a member exited before the start): one
        // started after that would be stopped only at the next level, stop_s later.
        if (result_.interrupted || ended_ || stop_level_ > 0 ||
            (has_coordinator() && next > 0 && !children_[0].running)) {
          say("the run ended while processes were starting; " + c_.processes[next].name +
              " and the rest were not started");
          stopped_starting = true;
        } else {
          spawn(next, c_.processes[next].argv, c_.processes[next].log);
          ++next;
        }
      }
      const bool starting = next < c_.processes.size() && !stopped_starting;
      if (!starting && running_count() == 0) break;
      wait_events(starting ? 0 : timeout_ms());
      check_deadline();
    }
    result_.status = status_;
    return result_;
  }

 private:
  bool has_coordinator() const {
    return !c_.processes.empty() && c_.processes[0].name == "coordinator";
  }

  void say(const std::string& s) {
    if (c_.say) c_.say(s);
  }

  void setup() {
    epoll_ = ::epoll_create1(EPOLL_CLOEXEC);
    if (epoll_ < 0) fail("epoll_create1");
    sigset_t mask;
    sigemptyset(&mask);
    for (int s : kSignals) sigaddset(&mask, s);
    if (::sigprocmask(SIG_BLOCK, &mask, &old_mask_) != 0) fail("sigprocmask");
    // An ignored signal is discarded, never queued for the signalfd, and a launcher may have
    // been started with INT ignored (a background job of a non-interactive shell, e.g. under
    // srun): while blocked, the default disposition only makes the signal pending.
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    for (std::size_t k = 0; k < kSignals.size(); ++k) {
      ::sigaction(kSignals[k], &dfl, &old_actions_[k]);
    }
    signals_blocked_ = true;
    signal_fd_ = ::signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
    if (signal_fd_ < 0) fail("signalfd");
    add(signal_fd_, kSignalTag);
    if (!c_.status_file.empty()) {
      inotify_ = ::inotify_init1(IN_CLOEXEC | IN_NONBLOCK);
      if (inotify_ < 0) fail("inotify_init1");
      const fs::path dir = fs::path(c_.status_file).parent_path();
      // The coordinator replaces the file by a rename into its folder.
      if (::inotify_add_watch(inotify_, dir.c_str(), IN_MOVED_TO | IN_CLOSE_WRITE) < 0) {
        fail("inotify_add_watch " + dir.string());
      }
      add(inotify_, kInotifyTag);
    }
  }

  void add(int fd, std::uint64_t tag) {
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = tag;
    if (::epoll_ctl(epoll_, EPOLL_CTL_ADD, fd, &ev) != 0) fail("epoll_ctl");
  }

  void spawn(std::size_t i, const std::vector<std::string>& argv, const std::string& log) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    // The child starts with the signal mask and dispositions a shell would give it: the
    // launcher's blocked signals (read through its signalfd) must reach the members.
    sigset_t none, defaults;
    sigemptyset(&none);
    sigemptyset(&defaults);
    for (int s : {SIGINT, SIGTERM, SIGHUP, SIGPIPE}) sigaddset(&defaults, s);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &defaults);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    pid_t pid = -1;
    const int rc = ::posix_spawn(&pid, args[0], &actions, &attr, args.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
    ProcessOutcome& out = result_.processes[i];
    out.log = log;
    if (rc != 0) {
      // As a shell reports a program it cannot run.
      std::ofstream(log, std::ios::app)
          << argv[0] << ": cannot start: " << std::strerror(rc) << "\n";
      out.status = 127;
      read_status();
      note_end(i);
      return;
    }
    Child& ch = children_[i];
    ch.pid = pid;
    ch.running = true;
    if (ch.pidfd >= 0) ::close(ch.pidfd);
    ch.pidfd = pidfd_open(pid);
    if (ch.pidfd < 0) fail("pidfd_open");
    add(ch.pidfd, i);
    if (!c_.pids_file.empty()) {
      std::ofstream f(c_.pids_file, std::ios::app);
      f << c_.processes[i].name << ' ' << (c_.host.empty() ? "" : c_.host + " ") << pid << '\n';
    }
  }

  std::size_t running_count() const {
    std::size_t n = 0;
    for (const auto& ch : children_) n += ch.running ? 1 : 0;
    return n;
  }

  int timeout_ms() const {
    double t = 1e9;
    if (deadline_) {
      t = std::chrono::duration<double>(*deadline_ - Clock::now()).count();
    }
    if (c_.status_remote) t = std::min(t, 1.0);
    if (t >= 1e8) return -1;
    return std::max(0, static_cast<int>(t * 1000.0) + 1);
  }

  void wait_events(int timeout) {
    epoll_event events[16];
    const int n = ::epoll_wait(epoll_, events, 16, timeout);
    if (n < 0) {
      if (errno == EINTR) return;
      fail("epoll_wait");
    }
    for (int k = 0; k < n; ++k) {
      const std::uint64_t tag = events[k].data.u64;
      if (tag == kSignalTag) {
        on_signal();
      } else if (tag == kInotifyTag) {
        drain_inotify();
      } else {
        on_exit(static_cast<std::size_t>(tag));
      }
    }
    if (c_.status_remote) read_status();
  }

  void on_signal() {
    signalfd_siginfo info;
    while (::read(signal_fd_, &info, sizeof info) == sizeof info) {
      if (!result_.interrupted) {
        result_.interrupted = true;
        if (running_count() > 0 && stop_level_ == 0) {
          say("interrupted; stopping every process");
          stop_all(SIGTERM, 1);
        }
      }
    }
  }

  void drain_inotify() {
    alignas(inotify_event) char buffer[4096];
    while (::read(inotify_, buffer, sizeof buffer) > 0) {
    }
    read_status();
  }

  void read_status() {
    if (c_.status_file.empty()) return;
    auto s = read_run_status(c_.status_file);
    if (!s) return;
    status_ = s;
    // On a host without the coordinator the status is the only word of the run's end.
    if (!has_coordinator() && s->ended() && !ended_) {
      ended_ = true;
      if (!deadline_) deadline_ = Clock::now() + seconds(c_.grace_s);
    }
  }

  static Clock::duration seconds(double s) {
    return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
  }

  void on_exit(std::size_t i) {
    Child& ch = children_[i];
    if (!ch.running) return;
    int wstatus = 0;
    if (::waitpid(ch.pid, &wstatus, WNOHANG) != ch.pid) return;  // not yet (spurious wake)
    ::epoll_ctl(epoll_, EPOLL_CTL_DEL, ch.pidfd, nullptr);
    ::close(ch.pidfd);
    ch.pidfd = -1;
    ch.running = false;
    ProcessOutcome& out = result_.processes[i];
    out.signaled = WIFSIGNALED(wstatus);
    out.status = out.signaled ? 128 + WTERMSIG(wstatus) : WEXITSTATUS(wstatus);
    const std::string& name = c_.processes[i].name;
    read_status();  // the newest word on the run before deciding
    const bool run_going_on = status_ && status_->started() && !status_->ended() &&
                              (!has_coordinator() || children_[0].running);
    // Only a process that died (killed by a signal) is restarted: one that ended by itself
    // (aborted run, own failure, interrupt) was told to or would fail again.
    if (c_.recover && name != "coordinator" && out.signaled && WTERMSIG(wstatus) != SIGINT &&
        run_going_on && !result_.interrupted && !deadline_ && out.restarts < c_.max_restarts) {
      ++out.restarts;
      say(name + " was killed by signal " + std::to_string(WTERMSIG(wstatus)) +
          "; restarting it (" + std::to_string(out.restarts) + " of at most " +
          std::to_string(c_.max_restarts) + ")");
      // It rejoins from the coordinator's rollback (docs/checkpoints.md).
      auto argv = c_.processes[i].argv;
      argv.push_back("--rejoin");
      std::string log = c_.processes[i].log;
      const auto dot = log.rfind(".log");
      log = (dot == std::string::npos ? log : log.substr(0, dot)) + ".restart" +
            std::to_string(out.restarts) + ".log";
      out.status = -1;
      out.signaled = false;
      spawn(i, argv, log);
      return;
    }
    note_end(i);
  }

  // Process i has ended for good (exited, or could not be started).
  void note_end(std::size_t i) {
    const std::string& name = c_.processes[i].name;
    const ProcessOutcome& out = result_.processes[i];
    if (name == "coordinator") {
      ended_ = true;
      if (!deadline_) deadline_ = Clock::now() + seconds(c_.grace_s);
      return;
    }
    // Until the run has started, a member that exits can never join: the run cannot start,
    // and waiting out the join timeout would only hide why.
    if (result_.early.empty() && !(status_ && status_->started()) && !result_.interrupted &&
        stop_level_ == 0 && !ended_) {
      result_.early =
          name + " exited (status " + std::to_string(out.status) + ") before the run started";
      result_.early_log = out.log;
      say(result_.early + "; stopping every process");
      stop_all(SIGTERM, 1);
    }
  }

  void stop_all(int sig, int level) {
    for (const auto& ch : children_) {
      if (ch.running) {
        ::kill(ch.pid, sig);
        result_.stopped_any = true;
      }
    }
    stop_level_ = level;
    deadline_ = Clock::now() + seconds(c_.stop_s);
  }

  void check_deadline() {
    if (!deadline_ || Clock::now() < *deadline_ || running_count() == 0) return;
    if (stop_level_ < 2) {
      if (stop_level_ == 0) say("processes still running after the end of the run; stopping them");
      stop_all(SIGTERM, 2);
    } else {
      stop_all(SIGKILL, 3);
      deadline_.reset();
    }
  }

  SupervisorConfig& c_;
  SupervisorResult result_;
  std::vector<Child> children_;
  std::optional<RunStatus> status_;
  std::optional<Clock::time_point> deadline_;
  int stop_level_ = 0;  // 0 none, 1 TERM (early, interrupt), 2 TERM after the grace, 3 KILL
  bool ended_ = false;
  int epoll_ = -1;
  int signal_fd_ = -1;
  int inotify_ = -1;
  static constexpr std::array<int, 3> kSignals{SIGINT, SIGTERM, SIGHUP};
  sigset_t old_mask_{};
  std::array<struct sigaction, 3> old_actions_{};
  bool signals_blocked_ = false;
};

}  // namespace

std::optional<RunStatus> read_run_status(const std::string& path) {
  if (!std::filesystem::exists(path)) return std::nullopt;
  try {
    const auto j = nlohmann::json::parse(read_text(path));
    RunStatus s;
    s.run_id = j.value("run_id", "");
    s.scenario = j.value("scenario", "");
    s.pid = j.value("pid", 0L);
    s.state = j.value("state", "");
    s.frame = j.value("frame", -1LL);
    s.recoveries = j.value("recoveries", 0LL);
    s.reason = j.value("reason", "");
    s.exit_code = j.value("exit_code", -1);
    if (j.contains("failed_after_end")) {
      s.failed_after_end = j.at("failed_after_end").get<std::map<std::string, std::string>>();
    }
    s.final = j.value("final", false);
    return s;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
}

const ProcessOutcome* SupervisorResult::find(const std::string& name) const {
  for (const auto& p : processes) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

Supervisor::Supervisor(SupervisorConfig config) : config_(std::move(config)) {}

SupervisorResult Supervisor::run() {
  Loop loop(config_);
  return loop.run();
}

std::string describe_exit(const ProcessOutcome& p) {
  if (p.signaled && p.status == 128 + SIGINT) return p.name + " was interrupted";
  if (p.signaled) return p.name + " was killed by signal " + std::to_string(p.status - 128);
  if (p.status == 130) return p.name + " was interrupted";
  return p.name + " exited with status " + std::to_string(p.status);
}

std::string read_text(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string last_line(const std::string& path) {
  std::ifstream in(path);
  std::string line, last;
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  }
  return last;
}

}  // namespace syndds::launch
