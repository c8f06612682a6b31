#pragma once
// main() of a member service: build one agent from the scenario and run it over DDS. This
// header is kept free of Fast DDS, the agents and spdlog (the body is in service_member.cpp), so
// that a service main compiles its options only.
#include <CLI/CLI.hpp>

#include <functional>
#include <string>

#include "scenario/scenario.hpp"

namespace syndds::proto {
class Agent;
}

namespace syndds::service {

/// `make_member_id(scenario)` names the member this process plays. `recorder_output`, when not
/// null, is the variable of the program's --output option (read after parsing): the member
/// writes its files there (the recorder, a sensor's saved frames). `configure` is called with
/// the agent before the run starts.
int member_main(const char* name, const char* description, int argc, char** argv,
                const std::function<void(CLI::App&)>& add_options,
                const std::function<std::string(const scenario::Scenario&)>& make_member_id,
                const std::string* recorder_output = nullptr,
                const std::function<void(proto::Agent&)>& configure = {});

}  // namespace syndds::service
