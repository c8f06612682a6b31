// syndds_sim: every agent of a scenario in one process, with the same frame semantics as the
// distributed run (the recorded results are byte-identical). For debugging, training and
// determinism checks.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "agents/agent_factory.hpp"
#include "common/service_cli.hpp"
#include "learn/policy_controller.hpp"
#include "protocol/local_runner.hpp"

using namespace syndds;
namespace sdds = syndds::dds;

int main(int argc, char** argv) {
  learn::register_policy_controller();
  CLI::App app{"syndds single-process runner: all agents of a scenario in one process"};
  service::CommonArgs common;
  service::add_common_options(app, common);
  std::string output = "runs/latest";
  bool quiet = false;
  app.add_option("--output", output, "Run directory")->capture_default_str();
  app.add_flag("--quiet", quiet, "Do not print the summary");
  return service::run_service("sim", app, argc, argv, common, [&] {
    const auto s = service::load_scenario(common);
    const std::string run_id = service::dds_options(common, s).run_id;  // validated
    proto::LocalRunner runner(
        agents::make_all_agents(s, record::RecorderOptions{output, run_id, "single-process"}),
        {s.time.final_frame(), s.time.heartbeat_s, s.time.realtime});
    const auto end = runner.run(&service::interrupted());
    if (!quiet && s.recorder.enabled) {
      std::ifstream summary(output + "/summary.txt");
      std::cout << summary.rdbuf();
    }
    return end.status == proto::RunStatus::completed ? sdds::kExitCompleted
                                                      : sdds::kExitInterrupted;
  });
}
