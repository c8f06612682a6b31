#pragma once
// The launcher's command line (run_scenario.sh's): what it parses, and the options of a run that
// RUN_DIR/launch.args records so that --resume can start the run again the same way.
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace syndds::launch {

/// A bad command line or launch.args; the message names the option or file.
struct LaunchError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The options that make the run what it is (scenario overrides, DDS setup, process layout, run
/// id), in the order first given.
struct RunOptions {
  std::vector<std::string> keys;
  std::map<std::string, std::string> values;
  /// Sets `key` (a flag has value ""); with keep_typed, a key already set stays as it was.
  void set(const std::string& key, const std::string& value, bool keep_typed = false);
  std::string get(const std::string& key) const;
  bool has(const std::string& key) const { return values.count(key) > 0; }
};

struct LaunchArgs {
  std::string scenario, output, resume, from = "latest";
  bool single = false, print = false, view = false, print_tasks = false, help = false;
  std::string view_port = "8080", view_bind = "127.0.0.1";
  std::string bin_dir, hosts, slots, host;
  RunOptions run;
};

/// argv without the program's name: [SCENARIO] options. The scenario comes first unless the
/// line starts with --resume. Throws LaunchError.
LaunchArgs parse_launch_args(const std::vector<std::string>& argv);

/// With --resume RUN_DIR: RUN_DIR/launch.args gives the scenario (unless one was typed) and the
/// run's options (those typed now win). Without the file a typed scenario is needed. Throws
/// LaunchError.
void merge_recorded(LaunchArgs& a);

/// Writes OUTPUT/launch.args: the scenario, then the run's options, one argument per line, paths
/// made absolute (a resume may be typed in another folder). Throws LaunchError.
void write_launch_args(const LaunchArgs& a, const std::string& output);

/// The run's options as every process of it takes them (--run-id and --processes left out), and
/// the --processes layout ("" if none).
std::vector<std::string> process_options(const LaunchArgs& a, std::string& layout);

}  // namespace syndds::launch
