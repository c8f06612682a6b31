#pragma once
// The processes of a distributed run, as syndds_plan prints them and syndds_launch starts them:
// the coordinator first, then one process per member (or per group of members, after the
// process layout), each with the arguments every process of the run must agree on.
#include <string>
#include <vector>

#include "common/service_cli.hpp"

namespace syndds::service {

struct PlannedProcess {
  std::string name;               // "coordinator", "vehicle/a", "recorder", "group/a", ...
  std::vector<std::string> argv;  // argv[0] is the program's path
};

struct PlanOptions {
  std::string output = "runs/latest";  // the run directory
  std::string bin_dir;                 // folder of the syndds_* programs
  std::string layout;                  // --processes override ("" = the scenario's)
};

/// The run's processes. Throws ConfigError for a bad layout.
std::vector<PlannedProcess> plan_run(const CommonArgs& common, const scenario::Scenario& s,
                                     const PlanOptions& options);

/// `s` quoted for a POSIX shell (unchanged when it has no character a shell treats specially).
std::string shell_quote(const std::string& s);
/// argv as one shell command line.
std::string shell_command(const std::vector<std::string>& argv);

/// The vehicle a process belongs to ("vehicle/a", "controller/a", "sensor/a", "group/a" -> "a"),
/// or "" for the run's own processes (coordinator, recorder): processes of one vehicle are
/// placed on one host.
std::string vehicle_of_process(const std::string& name);

/// Places the processes on hosts with `slots` task slots each: the coordinator, the recorder
/// (anything not of a vehicle) on host 0; the processes of one vehicle together, so that what
/// they exchange every frame goes over shared memory; vehicles in plan order to the host whose
/// processes per slot stay lowest (the first such host on ties). Returns each process's host.
std::vector<int> place_processes(const std::vector<PlannedProcess>& processes,
                                 const std::vector<int>& slots);

}  // namespace syndds::service
