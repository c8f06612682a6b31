#include "common/run_plan.hpp"

#include <filesystem>
#include <map>

#include "core/error.hpp"
#include "dds/participant.hpp"

namespace syndds::service {

namespace fs = std::filesystem;

std::string shell_quote(const std::string& s) {
  if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                        "0123456789_-./:=,+@") == std::string::npos) {
    return s;
  }
  std::string out = "'";
  for (char c : s) out += (c == '\'') ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

std::string shell_command(const std::vector<std::string>& argv) {
  std::string out;
  for (const auto& a : argv) out += (out.empty() ? "" : " ") + shell_quote(a);
  return out;
}

std::string vehicle_of_process(const std::string& name) {
  if (name == "coordinator" || name == scenario::kRecorderMember) return "";
  const auto slash = name.find('/');
  return slash == std::string::npos ? "" : name.substr(slash + 1);
}

std::vector<int> place_processes(const std::vector<PlannedProcess>& processes,
                                 const std::vector<int>& slots) {
  std::vector<long> load(slots.size(), 0);
  std::vector<std::string> vehicles;  // in plan order
  std::map<std::string, long> count;
  for (const auto& p : processes) {
    const std::string v = vehicle_of_process(p.name);
    if (v.empty()) {
      ++load[0];
      continue;
    }
    if (count[v]++ == 0) vehicles.push_back(v);
  }
  std::map<std::string, int> host_of;
  for (const auto& v : vehicles) {
    const long c = count[v];
    std::size_t best = 0;
    for (std::size_t n = 1; n < slots.size(); ++n) {
      // (load[n] + c) / slots[n] < (load[best] + c) / slots[best], in integers
      if ((load[n] + c) * slots[best] < (load[best] + c) * slots[n]) best = n;
    }
    host_of[v] = static_cast<int>(best);
    load[best] += c;
  }
  std::vector<int> hosts;
  for (const auto& p : processes) {
    const std::string v = vehicle_of_process(p.name);
    hosts.push_back(v.empty() ? 0 : host_of[v]);
  }
  return hosts;
}

std::vector<PlannedProcess> plan_run(const CommonArgs& common, const scenario::Scenario& s,
                                     const PlanOptions& options) {
  const std::string run_id = dds_options(common, s).run_id;  // validated
  const auto program = [&](const char* name) {
    return (fs::path(options.bin_dir) / name).string();
  };
  // Everything that must agree across processes is passed to every one of them.
  std::vector<std::string> shared = {fs::absolute(common.scenario_file).string(),
                                     "--run-id",
                                     run_id,
                                     "--domain",
                                     std::to_string(s.dds.domain_id),
                                     "--config-dir",
                                     fs::absolute(common.config_dir).string()};
  const auto add = [&](std::initializer_list<std::string> args) {
    shared.insert(shared.end(), args.begin(), args.end());
  };
  if (common.duration_s) add({"--duration", std::to_string(*common.duration_s)});
  if (common.realtime) add({"--realtime"});
  if (common.transport) add({"--transport", *common.transport});
  if (common.discovery_server) add({"--discovery-server", *common.discovery_server});
  if (!common.dds_profiles.empty()) add({"--dds-profiles", common.dds_profiles});
  if (!common.security_dir.empty()) {
    add({"--security-dir", fs::absolute(common.security_dir).string()});
  }
  if (common.log_level != "info") add({"--log-level", common.log_level});
  // Checkpoints go to the run directory (docs/checkpoints.md); a resumed run starts there.
  const std::string run_dir = fs::absolute(options.output).string();
  add({"--run-dir", run_dir});
  if (!common.resume_from.empty()) add({"--resume-from", common.resume_from});

  scenario::ProcessLayout layout = s.processes;
  if (!options.layout.empty()) {
    const auto l = scenario::ProcessLayout::parse(options.layout);
    if (!l) {
      throw ConfigError("--processes '" + options.layout +
                        "': " + scenario::ProcessLayout::kExpected);
    }
    layout = *l;
  }
  const auto command = [&](const char* name, std::initializer_list<std::string> tail) {
    std::vector<std::string> argv{program(name)};
    argv.insert(argv.end(), shared.begin(), shared.end());
    argv.insert(argv.end(), tail.begin(), tail.end());
    return argv;
  };
  // The command of a process hosting `members`: a member alone gets its own program (only the
  // learned-policy controller loads libtorch); several share one syndds_group process.
  auto command_of = [&](const std::vector<std::string>& members) {
    if (members.size() > 1) {
      auto argv = command("syndds_group", {});
      for (const auto& m : members) {
        argv.push_back("--member");
        argv.push_back(m);
      }
      argv.push_back("--output");
      argv.push_back(run_dir);
      return argv;
    }
    const std::string& m = members.front();
    if (m == scenario::kRecorderMember) return command("syndds_recorder", {"--output", run_dir});
    const auto slash = m.find('/');
    const std::string kind = m.substr(0, slash);
    const std::string id = m.substr(slash + 1);
    if (kind == "vehicle") return command("syndds_vehicle", {"--vehicle", id});
    if (kind == "sensor") return command("syndds_sensor", {"--vehicle", id, "--output", run_dir});
    const bool policy = s.find_vehicle(id)->controller.type == "policy";
    return command(policy ? "syndds_policy_controller" : "syndds_controller", {"--vehicle", id});
  };
  std::vector<PlannedProcess> processes;
  processes.push_back({"coordinator", command("syndds_coordinator", {})});
  for (const auto& members : s.process_members(layout)) {
    // A process of several members is named after its first vehicle: group/<id>.
    const std::string& first = members.front();
    const std::string name =
        members.size() == 1 ? first : "group/" + first.substr(first.find('/') + 1);
    processes.push_back({name, command_of(members)});
  }
  return processes;
}

}  // namespace syndds::service
