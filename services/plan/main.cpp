// syndds_plan: validates a scenario and prints the command line of every process of the run,
// so the launcher (or any other launcher, on any hosts) can start them.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "common/service_cli.hpp"

using namespace syndds;
namespace sdds = syndds::dds;
namespace fs = std::filesystem;

namespace {

std::string quote(const std::string& s) {
  if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                        "0123456789_-./:=,+@") == std::string::npos) {
    return s;
  }
  std::string out = "'";
  for (char c : s) out += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"syndds plan: validate a scenario and print each process's command line"};
  service::CommonArgs common;
  service::add_common_options(app, common);
  std::string output = "runs/latest";
  std::string bin_dir;
  std::string format = "shell";
  app.add_option("--output", output, "Run directory (recorder)")->capture_default_str();
  app.add_option("--bin-dir", bin_dir, "Folder holding the syndds_* programs");
  app.add_option("--format", format,
                 "shell: one command per line; launcher: member<TAB>command; files: every file "
                 "the scenario loads (role, hash, bytes, path), to compare hosts")
      ->check(CLI::IsMember({"shell", "launcher", "files"}))
      ->capture_default_str();
  return service::run_service("plan", app, argc, argv, common, [&] {
    const auto s = service::load_scenario_config(common);
    if (format == "files") {
      std::printf("# fingerprint %016llx\n", static_cast<unsigned long long>(s.fingerprint));
      for (const auto& f : s.files) {
        std::printf("%s\t%016llx\t%llu\t%s\n", f.role.c_str(),
                    static_cast<unsigned long long>(f.hash),
                    static_cast<unsigned long long>(f.size), f.path.c_str());
      }
      return 0;
    }
    const std::string run_id = service::dds_options(common, s).run_id;  // validated
    const std::string bin = bin_dir.empty() ? fs::path(argv[0]).parent_path().string() : bin_dir;
    const auto program = [&](const char* name) {
      return quote((fs::path(bin) / name).string());
    };
    // Everything that must agree across processes is passed to every one of them.
    std::string shared = " " + quote(fs::absolute(common.scenario_file).string()) + " --run-id " +
                         quote(run_id) + " --domain " + std::to_string(s.dds.domain_id) +
                         " --config-dir " + quote(fs::absolute(common.config_dir).string());
    if (common.duration_s) shared += " --duration " + std::to_string(*common.duration_s);
    if (common.realtime) shared += " --realtime";
    if (common.transport) shared += " --transport " + *common.transport;
    if (common.discovery_server) shared += " --discovery-server " + quote(*common.discovery_server);
    if (!common.dds_profiles.empty()) shared += " --dds-profiles " + quote(common.dds_profiles);
    if (common.log_level != "info") shared += " --log-level " + common.log_level;

    std::vector<std::pair<std::string, std::string>> processes;
    processes.emplace_back("coordinator", program("syndds_coordinator") + shared);
    for (const auto& v : s.vehicles) {
      processes.emplace_back(scenario::vehicle_member(v.id),
                             program("syndds_vehicle") + shared + " --vehicle " + quote(v.id));
    }
    for (const auto& v : s.vehicles) {
      if (!v.controller.is_builtin()) continue;
      // Learned policies run in a program of their own: only it loads libtorch.
      const char* controller =
          v.controller.type == "policy" ? "syndds_policy_controller" : "syndds_controller";
      processes.emplace_back(scenario::controller_member(v.id),
                             program(controller) + shared + " --vehicle " + quote(v.id));
    }
    for (const auto& v : s.vehicles) {
      if (!v.has_rendered_sensors()) continue;
      processes.emplace_back(scenario::sensor_member(v.id),
                             program("syndds_sensor") + shared + " --vehicle " + quote(v.id) +
                                 " --output " + quote(fs::absolute(output).string()));
    }
    if (s.recorder.enabled) {
      processes.emplace_back(scenario::kRecorderMember,
                             program("syndds_recorder") + shared + " --output " +
                                 quote(fs::absolute(output).string()));
    }
    if (format == "shell") {
      std::cout << "# run '" << run_id << "' of " << s.file << " on DDS domain " << s.dds.domain_id
                << ": start these in any order, on any hosts\n";
      for (const auto& v : s.vehicles) {
        if (v.controller.type == "external") {
          std::cout << "# " << scenario::external_member(v.id)
                    << ": your own program (see docs/protocol.md, \"External controllers\")\n";
        }
      }
    }
    for (const auto& [member, command] : processes) {
      if (format == "launcher") {
        std::cout << member << '\t' << command << '\n';
      } else {
        std::cout << command << '\n';
      }
    }
    return 0;
  });
}
