// syndds_external_driver: an example external controller. It joins a run as the member
// "external/<vehicle>" and sends one constant command every frame. Values are passed through
// unchecked (the vehicle validates them), so it can also show how bad commands are rejected.
#include <spdlog/spdlog.h>

#include "agents/constant_driver_agent.hpp"
#include "common/service_cli.hpp"
#include "dds/member_runtime.hpp"

namespace service = syndds::service;

int main(int argc, char** argv) {
  CLI::App app{"syndds external driver: sends a constant command to one vehicle every frame"};
  service::CommonArgs common;
  service::DebugArgs debug;
  service::add_common_options(app, common);
  service::add_debug_options(app, debug);
  std::string vehicle;
  syndds::vehicle::DriverInputs cmd;
  std::string throttle_text = "0.3";
  app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
  app.add_option("--steering", cmd.steering, "Steering in [-1, 1]")->capture_default_str();
  app.add_option("--throttle", throttle_text, "Throttle in [0, 1] (\"nan\" is sent as NaN)")
      ->capture_default_str();
  app.add_option("--braking", cmd.braking, "Braking in [0, 1]")->capture_default_str();
  return service::run_service("external_driver", app, argc, argv, common, [&] {
    cmd.throttle = std::stod(throttle_text);
    const auto s = service::load_scenario(common);
    const auto* v = s.find_vehicle(vehicle);
    if (!v || v->controller.type != "external") {
      throw syndds::ConfigError(s.file + ": vehicle '" + vehicle +
                                "' has no `controller: {type: external}`");
    }
    syndds::agents::ConstantDriverAgent agent(syndds::scenario::external_member(vehicle), vehicle,
                                              cmd);
    syndds::dds::MemberRuntime runtime(agent, service::member_options(common, debug, s));
    const int code = runtime.run(service::interrupted());
    if (code != syndds::dds::kExitCompleted) {
      spdlog::error("{}: run ended: {}", agent.member_id(), runtime.end_reason());
    }
    {
      service::DdsTeardownGuard guard(code);
      runtime.close();
    }
    return code;
  });
}
