#include "launch/launch_args.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

namespace syndds::launch {
namespace {

namespace fs = std::filesystem;

bool is_run_option(const std::string& o) {
  static const char* k[] = {"--run-id",           "--duration",  "--domain",       "--transport",
                            "--discovery-server", "--log-level", "--dds-profiles", "--config-dir",
                            "--security-dir",     "--processes"};
  for (const char* x : k) {
    if (o == x) return true;
  }
  return false;
}

// Options of the command line into `a`; with keep_typed (launch.args), run options already set
// stay as typed.
void parse_into(LaunchArgs& a, const std::vector<std::string>& argv, bool keep_typed) {
  for (std::size_t i = 0; i < argv.size(); ++i) {
    const std::string& o = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argv.size()) throw LaunchError(o + " needs a value");
      return argv[++i];
    };
    if (is_run_option(o)) {
      a.run.set(o, value(), keep_typed);
    } else if (o == "--realtime") {
      a.run.set(o, "", keep_typed);
    } else if (keep_typed) {
      throw LaunchError("unknown option in launch.args: " + o);
    } else if (o == "--output") {
      a.output = value();
    } else if (o == "--resume") {
      a.resume = value();
    } else if (o == "--from-frame") {
      a.from = value();
    } else if (o == "--single-process") {
      a.single = true;
    } else if (o == "--print-commands") {
      a.print = true;
    } else if (o == "--view") {
      a.view = true;
    } else if (o == "--view-port") {
      a.view_port = value();
    } else if (o == "--view-bind") {
      a.view_bind = value();
    } else if (o == "--bin-dir") {
      a.bin_dir = value();
    } else if (o == "--hosts") {
      a.hosts = value();
    } else if (o == "--slots") {
      a.slots = value();
    } else if (o == "--host") {
      a.host = value();
    } else if (o == "--print-tasks") {
      a.print_tasks = true;
    } else if (o == "-h" || o == "--help") {
      a.help = true;
    } else {
      throw LaunchError("unknown option: " + o + " (see --help)");
    }
  }
}

}  // namespace

void RunOptions::set(const std::string& key, const std::string& value, bool keep_typed) {
  if (values.count(key)) {
    if (keep_typed) return;
  } else {
    keys.push_back(key);
  }
  values[key] = value;
}

std::string RunOptions::get(const std::string& key) const {
  const auto it = values.find(key);
  return it == values.end() ? "" : it->second;
}

LaunchArgs parse_launch_args(const std::vector<std::string>& argv) {
  LaunchArgs a;
  std::vector<std::string> rest = argv;
  if (!rest.empty() && rest[0] != "--resume" && rest[0] != "-h" && rest[0] != "--help") {
    a.scenario = rest[0];
    rest.erase(rest.begin());
  }
  parse_into(a, rest, false);
  return a;
}

void merge_recorded(LaunchArgs& a) {
  if (a.resume.empty()) return;
  const fs::path recorded = fs::path(a.resume) / "launch.args";
  if (!fs::exists(recorded)) {
    if (!a.scenario.empty()) return;
    throw LaunchError("--resume " + a.resume +
                      ": no launch.args there (the run was not started by this launcher, or by "
                      "an older one): name the scenario and its overrides again: "
                      "run_scenario.sh SCENARIO.yaml --resume " +
                      a.resume + " [options]");
  }
  std::ifstream in(recorded);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  if (lines.empty() || lines[0].empty()) {
    throw LaunchError("--resume " + a.resume + ": " + recorded.string() + " is empty");
  }
  if (a.scenario.empty()) a.scenario = lines[0];
  parse_into(a, std::vector<std::string>(lines.begin() + 1, lines.end()), true);
}

void write_launch_args(const LaunchArgs& a, const std::string& output) {
  std::vector<std::string> lines{fs::absolute(a.scenario).string()};
  for (const auto& k : a.run.keys) {
    std::string v = a.run.get(k);
    if (k == "--config-dir" || k == "--dds-profiles" || k == "--security-dir") {
      v = fs::absolute(v).lexically_normal().string();
    }
    lines.push_back(k);
    if (k != "--realtime") lines.push_back(v);
  }
  for (const auto& l : lines) {
    if (l.find('\n') != std::string::npos) {
      throw LaunchError("cannot record an argument with a line break for --resume: " + l);
    }
  }
  std::error_code ec;
  fs::create_directories(output, ec);
  const fs::path file = fs::path(output) / "launch.args";
  {
    std::ofstream out(file.string() + ".tmp");
    for (const auto& l : lines) out << l << '\n';
    if (!out) throw LaunchError("cannot write " + file.string());
  }
  fs::rename(file.string() + ".tmp", file, ec);
  if (ec) throw LaunchError("cannot write " + file.string() + ": " + ec.message());
}

std::vector<std::string> process_options(const LaunchArgs& a, std::string& layout) {
  std::vector<std::string> pass;
  layout.clear();
  for (const auto& k : a.run.keys) {
    if (k == "--run-id") continue;
    if (k == "--processes") {
      layout = a.run.get(k);
    } else if (k == "--realtime") {
      pass.push_back(k);
    } else {
      pass.push_back(k);
      pass.push_back(a.run.get(k));
    }
  }
  return pass;
}

}  // namespace syndds::launch
