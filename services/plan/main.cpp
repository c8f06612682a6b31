// syndds_plan: validates a scenario and prints the command line of every process of the run,
// so the launcher (or any other launcher, on any hosts) can start them.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "common/service_cli.hpp"
#include "core/error.hpp"

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
  std::string layout_option;
  app.add_option("--output", output, "Run directory (recorder)")->capture_default_str();
  app.add_option("--bin-dir", bin_dir, "Folder holding the syndds_* programs");
  app.add_option("--format", format,
                 "shell: one command per line; launcher: member<TAB>command; files: every file "
                 "the scenario loads (role, hash, bytes, path), to compare hosts; policy: the "
                 "on_member_loss policy and max_recoveries")
      ->check(CLI::IsMember({"shell", "launcher", "files", "policy"}))
      ->capture_default_str();
  app.add_option("--processes", layout_option,
                 "Process layout: per_member, per_vehicle or a number of processes for the "
                 "vehicles (overrides the scenario's processes:; results are the same)");
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
    if (format == "policy") {
      // For the launcher: what it does when a member's process dies (restart it under recover).
      const auto p = s.coordinator.on_member_loss;
      std::printf("%s %d\n",
                  p == proto::LossPolicy::recover        ? "recover"
                  : p == proto::LossPolicy::continue_run ? "continue"
                                                         : "abort",
                  s.coordinator.max_recoveries);
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
    if (!common.security_dir.empty()) {
      shared += " --security-dir " + quote(fs::absolute(common.security_dir).string());
    }
    if (common.log_level != "info") shared += " --log-level " + common.log_level;
    // Checkpoints go to the run directory (docs/checkpoints.md); a resumed run starts there.
    const std::string run_dir = quote(fs::absolute(output).string());
    shared += " --run-dir " + run_dir;
    if (!common.resume_from.empty()) shared += " --resume-from " + quote(common.resume_from);

    scenario::ProcessLayout layout = s.processes;
    if (!layout_option.empty()) {
      const auto l = scenario::ProcessLayout::parse(layout_option);
      if (!l) {
        throw ConfigError("--processes '" + layout_option + "': " +
                          scenario::ProcessLayout::kExpected);
      }
      layout = *l;
    }
    // The command of a process hosting `members`: a member alone gets its own program (only
    // the learned-policy controller loads libtorch); several share one syndds_group process.
    auto command_of = [&](const std::vector<std::string>& members) {
      if (members.size() > 1) {
        std::string c = program("syndds_group") + shared;
        for (const auto& m : members) c += " --member " + quote(m);
        return c + " --output " + run_dir;
      }
      const std::string& m = members.front();
      if (m == scenario::kRecorderMember) {
        return program("syndds_recorder") + shared + " --output " + run_dir;
      }
      const auto slash = m.find('/');
      const std::string kind = m.substr(0, slash);
      const std::string id = m.substr(slash + 1);
      if (kind == "vehicle") return program("syndds_vehicle") + shared + " --vehicle " + quote(id);
      if (kind == "sensor") {
        return program("syndds_sensor") + shared + " --vehicle " + quote(id) + " --output " +
               run_dir;
      }
      const bool policy = s.find_vehicle(id)->controller.type == "policy";
      return program(policy ? "syndds_policy_controller" : "syndds_controller") + shared +
             " --vehicle " + quote(id);
    };
    std::vector<std::pair<std::string, std::string>> processes;
    processes.emplace_back("coordinator", program("syndds_coordinator") + shared);
    for (const auto& members : s.process_members(layout)) {
      // A process of several members is named after its first vehicle: group/<id>.
      const std::string& first = members.front();
      const std::string name =
          members.size() == 1 ? first : "group/" + first.substr(first.find('/') + 1);
      processes.emplace_back(name, command_of(members));
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
