// syndds_launch: starts every process of a distributed run on this host (or this host's share of
// a multi-host run), watches them until the run has ended, restarts members under
// on_member_loss: recover, and prints the run's summary or one line saying why it failed.
// launch_scripts/run_scenario.sh is this program; docs/deployment.md, "The launcher".
#include <fcntl.h>
#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "common/run_plan.hpp"
#include "common/service_cli.hpp"
#include "core/error.hpp"
#include "launch/launch_args.hpp"
#include "launch/shm_ports.hpp"
#include "launch/supervisor.hpp"
#include "launch/verdict.hpp"

namespace fs = std::filesystem;
namespace service = syndds::service;
namespace launch = syndds::launch;

extern char** environ;

namespace {

constexpr const char* kUsage =
    R"(Runs a scenario: one process per vehicle, controller, sensor and recorder plus the
coordinator, watched until the run ends; prints a short summary, or a one-line reason.

  run_scenario.sh SCENARIO.yaml [--output DIR] [--duration S] [--realtime]
      [--single-process] [--processes per_member|per_vehicle|N] [--print-commands]
      [--domain D] [--run-id ID] [--transport default|udp|udp_redundant]
      [--discovery-server ADDR:PORT] [--log-level LEVEL] [--security-dir DIR]
      [--config-dir DIR] [--dds-profiles FILE] [--view [--view-port P] [--view-bind ADDR]]
  run_scenario.sh [SCENARIO.yaml] --resume RUN_DIR [--from-frame K] [options]
  syndds_launch SCENARIO.yaml --hosts H1,H2,... [--slots S1,S2,...] [--host H] [--print-tasks]
      [options]    (one host's share of a multi-host run: launch_scripts/slurm/)

--view also starts the browser viewer (syndds_viewer, docs/viewer.md) on the live run and
prints its URL (port 8080 unless --view-port; 0: any free port; on 127.0.0.1 unless
--view-bind). It only reads: stopping it changes nothing in the run.

--processes overrides the scenario's process layout (docs/deployment.md, "Processes"); the
results are byte-identical whatever the layout.

--resume continues the run in RUN_DIR from its latest complete checkpoint (or the one of
frame K) with the same scenario and overrides (docs/checkpoints.md). The scenario and the
options of the run's first start are in RUN_DIR/launch.args: without SCENARIO they are used
again; options typed now win.

--hosts starts only the processes placed on this host (--host, default $SLURMD_NODENAME or
the host name): the coordinator and recorder on the first host, each vehicle's processes
together on the host whose processes per slot stay lowest. --print-tasks prints the placement.

The run's state is read from the coordinator's RUN_DIR/logs/run_status.json, never from a log.
Exit status: 0 completed, 1 bad scenario or command line or more than this host can start,
2 run aborted, a process failed, or the run completed without its recorder, 130 interrupted.
Logs of every process: OUTPUT/logs/.
)";

std::string g_me = "syndds_launch";

[[noreturn]] void die(const std::string& what, int code = 1) {
  std::cerr << g_me << ": " << what << std::endl;
  std::exit(code);
}
void say(const std::string& what) { std::cerr << g_me << ": " << what << std::endl; }

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, sep)) out.push_back(item);
  return out;
}

std::string stamp() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", std::localtime(&t));
  return buf;
}

long mem_available_mb() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  long kb = 0;
  std::string unit;
  while (in >> key >> kb >> unit) {
    if (key == "MemAvailable:") return kb / 1024;
  }
  return -1;
}

double env_double(const char* name, double fallback) {
  const char* v = std::getenv(name);
  if (v == nullptr || *v == '\0') return fallback;
  try {
    return std::stod(v);
  } catch (const std::exception&) {
    die(std::string(name) + "='" + v + "': expected a number");
  }
}

// Runs a program, waits for it, returns its exit status (127 if it cannot start).
int run_program(const std::vector<std::string>& argv, bool quiet) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (quiet) {
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  }
  pid_t pid;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return 127;
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

[[noreturn]] void exec(const std::vector<std::string>& argv) {
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::cout.flush();
  execv(args[0], args.data());
  die("cannot run " + argv[0] + ": " + std::strerror(errno));
}

void record_launch(const launch::LaunchArgs& a) {
  try {
    launch::write_launch_args(a, a.output);
  } catch (const launch::LaunchError& e) {
    die(e.what());
  }
}

}  // namespace

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::warn);  // the scenario loader's notes are for the services
  if (const char* me = std::getenv("SYNDDS_LAUNCH_NAME"); me != nullptr && *me != '\0') g_me = me;
  const std::vector<std::string> line(argv + 1, argv + argc);
  if (line.empty()) {
    std::cerr << kUsage;
    return 1;
  }
  launch::LaunchArgs a;
  try {
    a = launch::parse_launch_args(line);
  } catch (const launch::LaunchError& e) {
    die(e.what());
  }
  if (a.help) {
    std::cout << kUsage;
    return 0;
  }
  // The programs of the run are beside this one as it was called (a folder of links to them
  // counts as theirs), unless --bin-dir says otherwise.
  const std::string self = argv[0];
  const fs::path bin = !a.bin_dir.empty() ? fs::absolute(a.bin_dir)
                       : self.find('/') != std::string::npos
                           ? fs::absolute(self).parent_path()
                           : fs::canonical("/proc/self/exe").parent_path();
  for (const char* p : {"syndds_plan", "syndds_coordinator", "syndds_vehicle", "syndds_controller",
                        "syndds_policy_controller", "syndds_recorder", "syndds_sensor",
                        "syndds_group", "syndds_sim"}) {
    if (access((bin / p).c_str(), X_OK) != 0) {
      die((bin / p).string() + " is missing: run launch_scripts/setup.sh first");
    }
  }

  // RUN_DIR/launch.args: the scenario and the options of the run's first start.
  try {
    launch::merge_recorded(a);
  } catch (const launch::LaunchError& e) {
    die(e.what());
  }
  if (a.scenario.empty()) die("no scenario file given (see --help)");
  if (!fs::is_regular_file(a.scenario)) die("scenario file not found: " + a.scenario);

  std::string stem = fs::path(a.scenario).stem().string();
  for (char& c : stem) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '.' && c != '-') c = '_';
  }
  const std::string when = stamp();
  const std::string pid = std::to_string(getpid());
  std::string layout;
  std::vector<std::string> pass = launch::process_options(a, layout);
  if (!a.resume.empty()) {
    if (!a.output.empty() && a.output != a.resume) {
      die("--resume continues RUN_DIR in place: no --output");
    }
    if (!fs::is_directory(fs::path(a.resume) / "checkpoints")) {
      die("--resume " + a.resume +
          ": no checkpoints there (the scenario needs checkpoint: every_s)");
    }
    a.output = a.resume;
    pass.push_back("--resume-from");
    pass.push_back(a.from);
    // The logs of the interrupted attempt stay beside the new ones.
    if (fs::is_directory(fs::path(a.output) / "logs") && a.hosts.empty()) {
      std::error_code ec;
      fs::rename(fs::path(a.output) / "logs", fs::path(a.output) / ("logs.before-resume-" + when),
                 ec);
    }
  }
  // The pid keeps two launches of one scenario in the same second apart; the stem is cut so that
  // the run id stays within the 64 characters a run id may have (40 + 1 + 15 + 1 + at most 7).
  if (a.output.empty()) a.output = "runs/" + stem + "-" + when + "-" + pid;
  std::string run_id = a.run.get("--run-id");
  if (run_id.empty()) run_id = stem.substr(0, 40) + "-" + when + "-" + pid;

  if (a.single) {
    // One process has no DDS traffic to watch.
    if (a.view) {
      die("--view watches a distributed run; view a --single-process run afterwards with "
          "launch_scripts/view.sh OUTPUT");
    }
    std::vector<std::string> cmd{
        (bin / "syndds_sim").string(), a.scenario, "--output", a.output, "--run-id", run_id};
    cmd.insert(cmd.end(), pass.begin(), pass.end());
    if (a.print) {
      std::cout << service::shell_command(cmd) << std::endl;
      return 0;
    }
    if (a.resume.empty()) record_launch(a);
    const int rc = run_program(cmd, false);
    if (rc == 0) std::cout << "output: " << a.output << std::endl;
    return rc;
  }
  if (a.print) {
    std::vector<std::string> cmd{(bin / "syndds_plan").string(),
                                 a.scenario,
                                 "--output",
                                 a.output,
                                 "--run-id",
                                 run_id,
                                 "--bin-dir",
                                 bin.string()};
    if (!layout.empty()) {
      cmd.push_back("--processes");
      cmd.push_back(layout);
    }
    cmd.insert(cmd.end(), pass.begin(), pass.end());
    exec(cmd);
  }

  // The plan, with the options every process of the run gets (validated as they do).
  service::CommonArgs common;
  std::vector<service::PlannedProcess> plan;
  bool recover = false;
  int max_restarts = 0;
  int domain = 0;
  try {
    CLI::App app{"syndds launch"};
    service::add_common_options(app, common);
    std::vector<std::string> cli{a.scenario, "--run-id", run_id};
    cli.insert(cli.end(), pass.begin(), pass.end());
    std::reverse(cli.begin(), cli.end());  // CLI11 takes a vector in reverse order
    app.parse(cli);
    const auto s = service::load_scenario_config(common);
    service::PlanOptions po;
    po.output = a.output;
    po.bin_dir = bin.string();
    po.layout = layout;
    plan = service::plan_run(common, s, po);
    recover = s.coordinator.on_member_loss == syndds::proto::LossPolicy::recover;
    max_restarts = s.coordinator.max_recoveries;
    domain = s.dds.domain_id;
  } catch (const CLI::ParseError& e) {
    die(e.what());
  } catch (const std::exception& e) {
    die(e.what());
  }

  // This host's share: all of it, or under --hosts what the placement gives this host.
  std::vector<std::string> hosts =
      a.hosts.empty() ? std::vector<std::string>{} : split(a.hosts, ',');
  std::vector<int> host_of(plan.size(), 0);
  int me = 0;
  if (!hosts.empty()) {
    std::vector<int> slots;
    for (const auto& x : split(a.slots, ',')) {
      try {
        slots.push_back(std::max(1, std::stoi(x)));
      } catch (const std::exception&) {
        die("--slots '" + a.slots + "': expected task slots per host, e.g. 4,4");
      }
    }
    if (slots.size() != hosts.size()) slots.assign(hosts.size(), 1);
    host_of = service::place_processes(plan, slots);
    if (a.print_tasks) {
      std::cout << "task\tnode\tmember\tcommand\n";
      for (std::size_t i = 0; i < plan.size(); ++i) {
        std::cout << i << '\t' << hosts[host_of[i]] << '\t' << plan[i].name << '\t'
                  << service::shell_command(plan[i].argv) << '\n';
      }
      return 0;
    }
    std::string host = a.host;
    if (host.empty()) {
      if (const char* n = std::getenv("SLURMD_NODENAME"); n != nullptr) host = n;
    }
    if (host.empty()) {
      char name[256] = {};
      gethostname(name, sizeof name - 1);
      host = split(name, '.').front();
    }
    const auto it = std::find(hosts.begin(), hosts.end(), host);
    if (it == hosts.end()) die("this host (" + host + ") is not one of --hosts " + a.hosts);
    me = static_cast<int>(it - hosts.begin());
    a.host = host;
  }
  std::vector<service::PlannedProcess> mine;
  for (std::size_t i = 0; i < plan.size(); ++i) {
    if (host_of[i] == me) mine.push_back(plan[i]);
  }
  const bool coordinator_here = !mine.empty() && mine.front().name == "coordinator";

  // Refuse what this machine cannot start, before starting anything: every process of a run
  // holds about PROCESS_MB of memory (Fast DDS participant, shared-memory transport; measured in
  // docs/deployment.md), and the user may only have so many processes.
  const long process_mb = static_cast<long>(env_double("SYNDDS_PROCESS_MB", 100));
  const long group_mb = static_cast<long>(env_double("SYNDDS_GROUP_MB", 200));
  long groups = 0;
  for (const auto& p : mine) groups += p.name.rfind("group/", 0) == 0 ? 1 : 0;
  const long n = static_cast<long>(mine.size());
  const long need_mb = (n - groups) * process_mb + groups * group_mb;
  const long avail_mb = mem_available_mb();
  if (avail_mb >= 0 && need_mb > avail_mb) {
    die(std::to_string(n) + " processes need about " + std::to_string(need_mb) + " MB (" +
        std::to_string(process_mb) + " MB each, " + std::to_string(group_mb) +
        " MB a group process) but this machine has " + std::to_string(avail_mb) +
        " MB available: run fewer vehicles or spread the run over hosts (docs/deployment.md)");
  }
  rlimit nproc{};
  if (getrlimit(RLIMIT_NPROC, &nproc) == 0 && nproc.rlim_cur != RLIM_INFINITY) {
    long running = 0;
    const std::string uid = std::to_string(getuid());
    for (const auto& e : fs::directory_iterator("/proc")) {
      struct stat st {};
      if (std::isdigit(static_cast<unsigned char>(e.path().filename().string()[0])) &&
          stat(e.path().c_str(), &st) == 0 && st.st_uid == getuid()) {
        ++running;
      }
    }
    if (running + n > static_cast<long>(nproc.rlim_cur)) {
      die(std::to_string(n) + " processes would exceed this user's limit of " +
          std::to_string(nproc.rlim_cur) + " processes (" + std::to_string(running) +
          " running; ulimit -u)");
    }
  }

  // Shared-memory ports an earlier run on this domain left behind break the next one's
  // discovery (launch/shm_ports.hpp): remove those no process uses before starting any.
  if (!mine.empty()) {
    if (const auto stale = launch::remove_stale_shm_ports("/dev/shm", domain); !stale.empty()) {
      say("removed the shared-memory files of " + std::to_string(stale.size()) +
          " Fast DDS ports of DDS domain " + std::to_string(domain) +
          " that an earlier run left behind (no process used them)");
    }
  }

  const fs::path out(a.output);
  if (a.resume.empty() && hosts.empty()) record_launch(a);
  std::error_code ec;
  fs::create_directories(out / "logs", ec);
  if (ec) die("cannot create " + (out / "logs").string());
  const fs::path status_file = out / "logs" / "run_status.json";
  // A status left by an earlier attempt (a resumed run) must not be taken for this one's; with
  // --hosts the other hosts may read it before this one starts, so whoever starts the hosts'
  // launchers removes it first (run_scenario.sbatch does).
  if (coordinator_here) fs::remove(status_file, ec);
  if (hosts.empty()) std::ofstream(out / "logs" / "pids", std::ios::trunc);

  // The viewer is not a member: the launcher neither waits for it nor cares how it ends.
  pid_t viewer = -1;
  if (a.view && coordinator_here) {
    const fs::path url = out / "logs" / "viewer.url";
    fs::remove(url, ec);
    std::vector<std::string> cmd{(bin / "syndds_viewer").string(),
                                 a.scenario,
                                 "--run-id",
                                 run_id,
                                 "--port",
                                 a.view_port,
                                 "--bind",
                                 a.view_bind,
                                 "--url-file",
                                 url.string()};
    for (const auto& x : pass) cmd.push_back(x);
    if (access(cmd[0].c_str(), X_OK) != 0)
      die(cmd[0] + " is missing: run launch_scripts/setup.sh first");
    std::vector<char*> args;
    for (const auto& x : cmd) args.push_back(const_cast<char*>(x.c_str()));
    args.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    const std::string log = (out / "logs" / "viewer.log").string();
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    if (posix_spawn(&viewer, args[0], &actions, nullptr, args.data(), environ) != 0) viewer = -1;
    posix_spawn_file_actions_destroy(&actions);
    // Bounded wait for its address (up to 10 s), or its end.
    for (int i = 0; i < 100 && viewer > 0; ++i) {
      if (fs::file_size(url, ec) > 0 && !ec) break;
      if (waitpid(viewer, nullptr, WNOHANG) == viewer) {
        viewer = -1;
        break;
      }
      usleep(100000);
    }
    if (fs::file_size(url, ec) > 0 && !ec) {
      std::string u = launch::read_text(url.string());
      while (!u.empty() && (u.back() == '\n' || u.back() == '\r')) u.pop_back();
      say("viewer at " + u);
    } else {
      say("the viewer did not start (the run goes on): " + launch::last_line(log));
    }
  }

  launch::SupervisorConfig config;
  for (const auto& p : mine) {
    std::string file = p.name;
    std::replace(file.begin(), file.end(), '/', '_');
    config.processes.push_back({p.name, p.argv, (out / "logs" / (file + ".log")).string()});
  }
  config.status_file = status_file.string();
  config.status_remote = !coordinator_here;
  config.recover = recover;
  config.max_restarts = max_restarts;
  config.grace_s = env_double("SYNDDS_LAUNCH_GRACE_S", 20);
  config.pids_file = (out / "logs" / "pids").string();
  config.host = a.host;
  config.say = say;
  launch::SupervisorResult r;
  if (!mine.empty()) {
    say("started " + std::to_string(mine.size()) + " processes for run " + run_id + " (logs in " +
        (out / "logs").string() + ")");
    try {
      r = launch::Supervisor(config).run();
    } catch (const std::exception& e) {
      die(std::string("cannot watch the run's processes: ") + e.what(), 2);
    }
  }
  if (viewer > 0) {
    kill(viewer, SIGTERM);
    waitpid(viewer, nullptr, 0);
  }

  // A process killed by a signal leaves its Fast DDS shared-memory files behind, and new runs on
  // this machine then fail to open their ports for minutes: remove those of dead processes
  // (Fast DDS's own tool; files of running processes are left alone).
  for (const auto& p : r.processes) {
    if (p.signaled) {
      run_program({"fastdds", "shm", "clean"}, true);
      break;
    }
  }

  launch::VerdictInput vin;
  vin.run_dir = a.output;
  vin.decides = coordinator_here;
  vin.view = a.view;
  const launch::Verdict v = launch::verdict(r, vin);
  std::cout << v.out << std::flush;
  for (const auto& m : v.messages) say(m);
  return v.exit_code;
}
