#pragma once
// Builds the agents a scenario declares: all of them (single-process runs) or one member
// (one service process).
#include <functional>
#include <string>
#include <vector>

#include "protocol/agent.hpp"
#include "agents/recorder_agent.hpp"
#include "scenario/scenario.hpp"

namespace syndds::agents {

/// Makes the controller agent of a vehicle whose controller type lives outside this library.
using ControllerFactory = std::function<proto::AgentPtr(const scenario::Scenario&,
                                                        const scenario::VehicleConfig&)>;
/// Lets make_agent build controllers of `type` in this process (`policy`: the learned-policy
/// controller, registered by the programs that link libtorch; see learn/policy_controller.hpp).
void register_controller_type(const std::string& type, ControllerFactory factory);

/// The agent for `member_id` ("vehicle/v1", "controller/v1", "recorder").
/// Throws ConfigError if the scenario declares no such member or it is not built in (external).
proto::AgentPtr make_agent(const scenario::Scenario& scenario, const std::string& member_id,
                           const record::RecorderOptions& recorder_options);

/// Every built-in agent of the scenario, in member order.
std::vector<proto::AgentPtr> make_all_agents(const scenario::Scenario& scenario,
                                             const record::RecorderOptions& recorder_options);

/// Throws ConfigError naming the scenario and the first agent that cannot write checkpoints
/// (the scenario asks for checkpoints, or a run resumes from one).
void require_checkpoints(const scenario::Scenario& scenario, const proto::Agent& agent);

}  // namespace syndds::agents
