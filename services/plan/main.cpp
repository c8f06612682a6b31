// syndds_plan: validates a scenario and prints the command line of every process of the run,
// so the launcher (or any other launcher, on any hosts) can start them.
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "common/run_plan.hpp"
#include "common/service_cli.hpp"
#include "dds/participant.hpp"
#include "core/error.hpp"

using namespace syndds;
namespace sdds = syndds::dds;
namespace fs = std::filesystem;

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
    service::PlanOptions options;
    options.output = output;
    options.bin_dir = bin_dir.empty() ? fs::path(argv[0]).parent_path().string() : bin_dir;
    options.layout = layout_option;
    const auto processes = service::plan_run(common, s, options);
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
    for (const auto& p : processes) {
      if (format == "launcher") std::cout << p.name << '\t';
      std::cout << service::shell_command(p.argv) << '\n';
    }
    return 0;
  });
}
