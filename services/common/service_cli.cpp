#include "common/service_cli.hpp"

#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <unistd.h>

#include <cctype>
#include <charconv>
#include <csignal>
#include <regex>
#include <filesystem>
#include <iostream>

#include "core/cpu_policy.hpp"
#include "core/error.hpp"
#include "dds/member_runtime.hpp"
#include "record/checkpoint.hpp"

namespace syndds::service {
namespace {

std::atomic<bool> g_interrupted{false};
volatile std::sig_atomic_t g_teardown_code = 0;

extern "C" void on_signal(int) { g_interrupted.store(true); }
extern "C" void on_teardown_abort(int) {
  static const char note[] = "note: Fast DDS aborted while shutting down (known 2.9.1 assertion); "
                             "the run's outcome was already delivered\n";
  [[maybe_unused]] const auto n = write(2, note, sizeof note - 1);
  _exit(g_teardown_code);
}

}  // namespace

const std::atomic<bool>& interrupted() { return g_interrupted; }

DdsTeardownGuard::DdsTeardownGuard(int code) {
  g_teardown_code = code;
  std::signal(SIGABRT, on_teardown_abort);
}

DdsTeardownGuard::~DdsTeardownGuard() { std::signal(SIGABRT, SIG_DFL); }

void add_common_options(CLI::App& app, CommonArgs& a) {
  app.add_option("scenario", a.scenario_file, "Scenario YAML file")->required();
  app.add_option("--run-id", a.run_id,
                 "Run id (DDS partition); every process of a run must use the same one");
  app.add_option("--domain", a.domain_id, "DDS domain id (overrides dds.domain_id)")
      ->check(CLI::Range(0, 232));
  app.add_option("--duration", a.duration_s, "Simulated seconds (overrides time.end_time_s)");
  app.add_flag("--realtime", a.realtime, "Pace frames to the wall clock (overrides time.realtime)");
  app.add_option("--transport", a.transport,
                 "DDS transport: default (shared memory + UDP), udp, or udp_redundant (UDP, "
                 "every datagram sent twice, to two ports of its receiver: lossy networks)")
      ->check(CLI::IsMember({"default", "udp", "udp_redundant"}));
  app.add_option("--discovery-server", a.discovery_server,
                 "ADDR:PORT of a Fast DDS discovery server (networks without multicast)");
  app.add_option("--config-dir", a.config_dir, "Folder with vehicles/ and dds/")->capture_default_str();
  app.add_option("--dds-profiles", a.dds_profiles,
                 "Fast DDS QoS profiles XML (default: CONFIG_DIR/dds/profiles.xml)");
  app.add_option("--log-level", a.log_level, "trace, debug, info, warn, error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}))
      ->capture_default_str();
  app.add_option("--run-dir", a.run_dir,
                 "Run directory where checkpoints are written and read (docs/checkpoints.md)");
  app.add_option("--resume-from", a.resume_from,
                 "Resume from the complete checkpoint of this frame in --run-dir, or 'latest'");
  app.add_option("--security-dir", a.security_dir,
                 "DDS Security folder written by launch_scripts/make_security.sh (overrides "
                 "dds.security)");
  app.add_option("--cpu-policy", a.cpu_policy,
                 "CPU scheduling: batch (a woken process does not preempt the one that woke it: "
                 "fewer context switches per frame) or normal")
      ->check(CLI::IsMember({"batch", "normal"}))
      ->capture_default_str();
  app.add_flag("--rejoin", a.rejoin,
               "A member restarted after it was lost (on_member_loss: recover): join the run "
               "under way from the coordinator's rollback");
}

std::int64_t resume_frame(const CommonArgs& args, const std::string& run_dir) {
  if (run_dir.empty()) throw ConfigError("--resume-from needs --run-dir (where the checkpoints are)");
  if (args.resume_from == "latest") {
    const auto latest = record::latest_complete_checkpoint(run_dir);
    if (!latest) {
      throw ConfigError("--resume-from latest: " + run_dir +
                        " has no complete checkpoint (checkpoints/frame_*/complete.yaml)");
    }
    return *latest;
  }
  std::int64_t frame = -1;
  const auto& t = args.resume_from;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), frame);
  if (ec != std::errc() || end != t.data() + t.size() || frame < 0) {
    throw ConfigError("--resume-from '" + t + "': expected a frame number or 'latest'");
  }
  try {
    record::read_checkpoint_info(run_dir, frame);
  } catch (const core::StateError& e) {
    throw ConfigError(std::string("--resume-from: ") + e.what());
  }
  return frame;
}

void add_debug_options(CLI::App& app, DebugArgs& d) {
  const char* group = "Testing (fault injection; never needed in normal runs)";
  app.add_option("--debug-frame-delay-ms", d.frame_delay_ms, "Sleep this long in every frame")
      ->group(group)->check(CLI::Range(0, 60000));
  app.add_option("--debug-publish-delay-ms", d.publish_delay_ms,
                 "Report a frame done, then publish its data this much later")
      ->group(group)->check(CLI::Range(0, 60000));
  app.add_flag("--debug-skip-data-barrier", d.skip_data_barrier,
               "Start frames without waiting for announced data (shows why the barrier exists)")
      ->group(group);
  app.add_option("--debug-build-id", d.build_id,
                 "Announce this build identity instead of the program's own (another build)")
      ->group(group);
}

scenario::Scenario load_scenario_config(const CommonArgs& a) {
  scenario::Overrides o;
  o.duration_s = a.duration_s;
  if (a.realtime) o.realtime = true;
  o.domain_id = a.domain_id;
  auto s = scenario::load_scenario_config(a.scenario_file, o, a.config_dir);
  if (a.transport) s.dds.transport = *a.transport;
  if (a.discovery_server) s.dds.discovery_server = *a.discovery_server;
  // One line per process names every file's hash, so that the logs of a run refused for a
  // fingerprint mismatch already show which file differs; the paths come at debug level.
  std::string hashes;
  for (const auto& f : s.files) {
    hashes += fmt::format(" {}={:08x}", f.role, f.hash >> 32);
    spdlog::debug("config file {}: {:016x} {} bytes {}", f.role, f.hash, f.size, f.path);
  }
  spdlog::info("scenario '{}': fingerprint {:016x}; files:{}", s.name, s.fingerprint, hashes);
  return s;
}

std::string default_run_id(const scenario::Scenario& s) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(s.fingerprint));
  std::string name = s.name.substr(0, 48);
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '.' && c != '-') c = '_';
  }
  return name + "-" + std::string(hex).substr(0, 8);
}

dds::DdsOptions dds_options(const CommonArgs& a, const scenario::Scenario& s) {
  dds::DdsOptions d;
  d.domain_id = s.dds.domain_id;
  d.run_id = a.run_id.empty() ? default_run_id(s) : a.run_id;
  // The run id becomes a DDS partition name, where * ? [ would match other runs.
  if (!std::regex_match(d.run_id, std::regex("[A-Za-z0-9_.-]{1,64}"))) {
    throw ConfigError("--run-id '" + d.run_id + "': use 1-64 characters of [A-Za-z0-9_.-]");
  }
  d.transport = s.dds.transport;
  d.discovery_server = s.dds.discovery_server;
  d.profiles_file =
      a.dds_profiles.empty() ? (std::filesystem::path(a.config_dir) / "dds" / "profiles.xml").string()
                             : a.dds_profiles;
  d.security_dir = a.security_dir.empty() ? s.dds.security_dir : a.security_dir;
  if (a.rejoin) {
    // A killed process leaves its Fast DDS shared-memory ports behind, and a participant that
    // reuses them (the restarted process gets the dead one's participant id) is never heard
    // by the others, which still hold the dead port (measured: the rejoin timed out in 1 of 4
    // restarts of one member, in 3 of 3 of a group process, whose participant was made here
    // and not through member_options). Over UDP it is a new address to every peer.
    if (d.transport == "default") d.transport = "udp";
  }
  return d;
}

dds::MemberRuntimeOptions member_options(const CommonArgs& a, const DebugArgs& d,
                                         const scenario::Scenario& s) {
  dds::MemberRuntimeOptions o;
  o.dds = dds_options(a, s);
  o.config_fingerprint = s.fingerprint;
  o.config_files = fingerprint_lines(s.files);
  o.heartbeat_s = s.time.heartbeat_s;
  o.join_timeout_s = s.coordinator.join_timeout_s + 5.0;
  // Shorter than the coordinator's frame deadline: a member stuck waiting for announced data
  // reports which sample is missing before the coordinator can only say who is late.
  o.input_timeout_s = 0.75 * s.coordinator.frame_timeout_s;
  o.debug_frame_delay_ms = d.frame_delay_ms;
  o.debug_build_id = d.build_id;
  o.debug_publish_delay_ms = d.publish_delay_ms;
  o.debug_skip_data_barrier = d.skip_data_barrier;
  o.run_dir = a.run_dir;
  o.checkpoint_every = s.checkpoint.every_frames;
  if (s.checkpoint.enabled() && a.run_dir.empty()) {
    throw ConfigError(s.file + ": checkpoint: every_s is set; give the run directory the "
                      "checkpoints go to with --run-dir");
  }
  if (!a.resume_from.empty()) o.resume_frame = resume_frame(a, a.run_dir);
  o.rejoin = a.rejoin;
  if (a.rejoin && s.coordinator.on_member_loss != proto::LossPolicy::recover) {
    throw ConfigError("--rejoin: " + s.file + " does not recover lost members "
                      "(coordinator.on_member_loss is not recover)");
  }
  return o;
}

dds::MemberRuntimeOptions member_options(const CommonArgs& a, const DebugArgs& d,
                                         const scenario::Scenario& s, const std::string& member) {
  auto o = member_options(a, d, s);
  o.late_join = s.is_late_member(member);
  o.dds.identity = member;  // its certificate, under DDS Security
  return o;
}

int run_service(const char* name, CLI::App& app, int argc, char** argv, CommonArgs& common,
                const std::function<int()>& body) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  auto logger = spdlog::stderr_color_mt(name);
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%H:%M:%S.%e] [%n] [%^%l%$] %v");
  spdlog::set_level(spdlog::level::from_str(common.log_level));
  // SIGHUP too: a launcher's terminal that closes must end the run like Ctrl-C, with the
  // summary saying so, not kill the process where it stands.
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGHUP, on_signal);
  try {
    // Before DDS starts its threads: they inherit it.
    if (const std::string why = set_cpu_policy(common.cpu_policy); !why.empty()) {
      spdlog::warn("{} (running with the policy it has)", why);
    }
    return body();
  } catch (const ConfigError& e) {
    std::cerr << name << ": error: " << e.what() << std::endl;
    return dds::kExitConfigError;
  } catch (const std::exception& e) {
    std::cerr << name << ": failed: " << e.what() << std::endl;
    return dds::kExitFailed;
  }
}

}  // namespace syndds::service
