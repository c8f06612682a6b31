#include "agents/agent_factory.hpp"

#include "agents/controller_agent.hpp"
#include "agents/follower_agent.hpp"
#include "agents/sensor_agent.hpp"

#include <filesystem>
#include <map>
#include "agents/vehicle_agent.hpp"
#include "core/error.hpp"

namespace syndds::agents {
namespace {

std::map<std::string, ControllerFactory>& controller_types() {
  static std::map<std::string, ControllerFactory> types;
  return types;
}

}  // namespace

void register_controller_type(const std::string& type, ControllerFactory factory) {
  controller_types()[type] = std::move(factory);
}

proto::AgentPtr make_agent(const scenario::Scenario& s, const std::string& member_id,
                           const record::RecorderOptions& recorder_options) {
  for (const auto& v : s.vehicles) {
    if (member_id == scenario::vehicle_member(v.id)) {
      return std::make_unique<VehicleAgent>(s, v);
    }
    if (member_id == scenario::controller_member(v.id) && v.controller.type == "path_follower") {
      return std::make_unique<ControllerAgent>(s, v);
    }
    if (member_id == scenario::controller_member(v.id) && v.controller.type == "follower") {
      return std::make_unique<FollowerAgent>(s, v);
    }
    if (member_id == scenario::controller_member(v.id) && v.controller.type == "policy") {
      const auto f = controller_types().find(v.controller.type);
      if (f == controller_types().end()) {
        throw ConfigError(s.file + ": vehicle " + v.id + ": controller type '" + v.controller.type +
                          "' runs in syndds_policy_controller or syndds_sim (this program does "
                          "not load learned policies)");
      }
      return f->second(s, v);
    }
    if (member_id == scenario::sensor_member(v.id) && v.has_rendered_sensors()) {
      return std::make_unique<SensorAgent>(
          s, v, SensorAgentOptions{(std::filesystem::path(recorder_options.output_dir) / "sensors").string(),
                             recorder_options.resume});
    }
    if (member_id == scenario::external_member(v.id) && v.controller.type == "external") {
      throw ConfigError(member_id + " is an external controller: it is the user's own program");
    }
  }
  if (member_id == scenario::kRecorderMember && s.recorder.enabled) {
    return std::make_unique<record::RecorderAgent>(s, recorder_options);
  }
  std::string known;
  for (const auto& m : s.member_ids()) known += (known.empty() ? "" : ", ") + m;
  throw ConfigError(s.file + ": scenario declares no member '" + member_id + "' (members: " +
                    known + ")");
}

std::vector<proto::AgentPtr> make_all_agents(const scenario::Scenario& s,
                                             const record::RecorderOptions& recorder_options) {
  std::vector<proto::AgentPtr> out;
  for (const auto& m : s.member_ids()) {
    if (m.rfind("external/", 0) == 0) {
      throw ConfigError(s.file + ": member " + m +
                        " is an external program; it cannot run in single-process mode");
    }
    out.push_back(make_agent(s, m, recorder_options));
  }
  return out;
}

void require_checkpoints(const scenario::Scenario& scenario, const proto::Agent& agent) {
  if (!agent.can_checkpoint()) {
    throw ConfigError(scenario.file + ": checkpoint: member " + agent.member_id() +
                      " cannot write checkpoints yet (docs/checkpoints.md lists the members "
                      "that can)");
  }
}

}  // namespace syndds::agents
