#pragma once
// What every service's main() shares: command-line options (CLI11), scenario loading with
// overrides, DDS options, logging, signal handling and the exit-code policy. A service main is
// then a few lines: parse, build the agent, run, return the exit code.
#include <CLI/CLI.hpp>

#include <atomic>
#include <functional>
#include <optional>
#include <string>

#include "scenario/scenario.hpp"

// The DDS layer's option structs (dds/participant.hpp, dds/member_runtime.hpp): a main that
// fills or reads them includes those headers; the others compile without Fast DDS.
namespace syndds::dds {
struct DdsOptions;
struct MemberRuntimeOptions;
}  // namespace syndds::dds

namespace syndds::service {

struct CommonArgs {
  std::string scenario_file;
  std::string run_id;
  std::optional<int> domain_id;
  std::optional<double> duration_s;
  bool realtime = false;
  std::optional<std::string> transport;
  std::optional<std::string> discovery_server;
  std::string config_dir = scenario::default_config_dir();
  std::string dds_profiles;
  std::string log_level = "info";
  /// Checkpoints (docs/checkpoints.md): the run directory they are written to and read from.
  std::string run_dir;
  /// Start from the complete checkpoint of this frame ("latest": the newest) in run_dir.
  std::string resume_from;
  /// Restarted after it was lost (on_member_loss: recover): joins the run under way and takes
  /// part from the coordinator's rollback (the launcher adds it).
  bool rejoin = false;
  /// DDS Security folder (overrides dds.security.dir; launch_scripts/make_security.sh).
  std::string security_dir;
  /// The process's CPU scheduling policy, set before any thread starts (core/cpu_policy.hpp):
  /// batch for the simulation's processes, normal for interactive ones (the viewer).
  std::string cpu_policy = "batch";
};

/// The frame --resume-from names in `run_dir` (a number, or "latest"); ConfigError if there is
/// no such complete checkpoint.
std::int64_t resume_frame(const CommonArgs& args, const std::string& run_dir);

struct DebugArgs {
  int frame_delay_ms = 0;
  int publish_delay_ms = 0;
  bool skip_data_barrier = false;
  std::string build_id;  // announce this build identity instead of the program's own
};

void add_common_options(CLI::App& app, CommonArgs& args);
void add_debug_options(CLI::App& app, DebugArgs& args);

/// Loads the scenario's configuration with the command-line overrides applied, and logs its
/// fingerprint with each file's role and hash (and path at debug level): compare them between
/// hosts when a member is refused for a different fingerprint. Builds no terrain, sensor or
/// vehicle.
scenario::Scenario load_scenario_config(const CommonArgs& args);
/// The same with the world resolved (obstacles on the ground) for the processes that simulate;
/// defined in syndds_service_member (services/common/service_member.cpp).
scenario::Scenario load_scenario(const CommonArgs& args);
/// The run id used when none is given: the scenario name and its fingerprint, so processes
/// started by hand from the same scenario agree.
std::string default_run_id(const scenario::Scenario& s);
dds::DdsOptions dds_options(const CommonArgs& args, const scenario::Scenario& s);
dds::MemberRuntimeOptions member_options(const CommonArgs& args, const DebugArgs& debug,
                                         const scenario::Scenario& s);
/// The same for one member (late joiners get their flag).
dds::MemberRuntimeOptions member_options(const CommonArgs& args, const DebugArgs& debug,
                                         const scenario::Scenario& s, const std::string& member);

/// Set by SIGINT / SIGTERM / SIGHUP.
const std::atomic<bool>& interrupted();

/// Scope of the DDS teardown, after the run's outcome was decided and delivered: Fast DDS 2.9.1
/// (Debian, assertions on) can abort in PDP::check_remote_participant_liveliness while many
/// participants leave at once. An abort inside this scope (and only there) ends the process
/// with `code` and a note on stderr instead of SIGABRT; nothing is left to deliver by then.
class DdsTeardownGuard {
 public:
  explicit DdsTeardownGuard(int code);
  ~DdsTeardownGuard();
  DdsTeardownGuard(const DdsTeardownGuard&) = delete;
  DdsTeardownGuard& operator=(const DdsTeardownGuard&) = delete;
};

/// Parses the command line, sets up logging and signals, calls `body`, and maps exceptions to
/// exit codes: ConfigError -> 1 (message names file:line:key), anything else -> 3.
int run_service(const char* name, CLI::App& app, int argc, char** argv, CommonArgs& common,
                const std::function<int()>& body);

}  // namespace syndds::service
