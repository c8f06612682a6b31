#include <spdlog/spdlog.h>

#include <optional>

#include "agents/agent_factory.hpp"
#include "common/member_main.hpp"
#include "common/service_cli.hpp"
#include "dds/member_runtime.hpp"
#include "scenario/scenario.hpp"

namespace syndds::service {

scenario::Scenario load_scenario(const CommonArgs& args) {
  auto s = load_scenario_config(args);
  scenario::place_obstacles(s);
  return s;
}

int member_main(const char* name, const char* description, int argc, char** argv,
                const std::function<void(CLI::App&)>& add_options,
                const std::function<std::string(const scenario::Scenario&)>& make_member_id,
                const std::string* recorder_output,
                const std::function<void(proto::Agent&)>& configure) {
  CLI::App app{description};
  CommonArgs common;
  DebugArgs debug;
  add_common_options(app, common);
  add_debug_options(app, debug);
  add_options(app);
  return run_service(name, app, argc, argv, common, [&] {
    const auto s = load_scenario(common);
    const std::string member = make_member_id(s);
    auto options = member_options(common, debug, s, member);
    // Once this member's outcome is settled, a Fast DDS abort while the run's participants
    // leave (a known 2.9.1 assertion) must not turn it into a crash.
    std::optional<DdsTeardownGuard> leaving;
    options.on_outcome = [&](int code) { leaving.emplace(code); };
    record::RecorderOptions ro;
    if (recorder_output) ro = record::RecorderOptions{*recorder_output, options.dds.run_id, "distributed"};
    ro.resume = options.resume_frame >= 0 || options.rejoin;
    auto agent = agents::make_agent(s, member, ro);
    if (options.checkpoint_every > 0 || options.resume_frame >= 0 || options.rejoin) {
      agents::require_checkpoints(s, *agent);
    }
    if (configure) configure(*agent);
    dds::MemberRuntime runtime(*agent, options);
    const int code = runtime.run(interrupted());
    if (code == dds::kExitCompleted) {
      spdlog::info("{}: run completed", member);
    } else {
      spdlog::error("{}: run ended: {}", member, runtime.end_reason());
    }
    {
      DdsTeardownGuard guard(code);
      runtime.close();
    }
    return code;
  });
}

}  // namespace syndds::service
