// syndds_group: several members of a run hosted by one process (a vehicle with its controller
// and sensors, or a share of the vehicles): one DDS participant and one discovery for all of
// them, samples between them delivered inside the process, each member still a barrier member
// of its own on its own thread. The recorded results are byte-identical to one process per
// member (docs/deployment.md, "Processes"). The launcher starts these when the scenario says
// `processes: per_vehicle` or a number.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "agents/agent_factory.hpp"
#include "common/service_cli.hpp"
#include "dds/done_batch.hpp"
#include "dds/grant_hub.hpp"
#include "dds/member_runtime.hpp"
#include "core/error.hpp"
#include "learn/register_policy_controller.hpp"

using namespace syndds;
namespace sdds = syndds::dds;

namespace {

// The exit code of the process from its members': its own failure first, then the run's
// verdict (every member of a run gets the same one), then an interrupt.
int combined_exit_code(const std::vector<int>& codes) {
  for (int worst :
       {sdds::kExitFailed, sdds::kExitRefused, sdds::kExitAborted, sdds::kExitInterrupted}) {
    if (std::find(codes.begin(), codes.end(), worst) != codes.end()) return worst;
  }
  return sdds::kExitCompleted;
}

}  // namespace

int main(int argc, char** argv) {
  learn::register_policy_controller();
  CLI::App app{"syndds group: several members of a run in one process (one DDS participant)"};
  service::CommonArgs common;
  service::DebugArgs debug;
  service::add_common_options(app, common);
  service::add_debug_options(app, debug);
  std::vector<std::string> members;
  std::string output = "runs/latest";
  app.add_option("--member", members,
                 "A member this process hosts (vehicle/ID, controller/ID, sensor/ID, recorder); "
                 "repeat for each")
      ->required();
  app.add_option("--output", output, "Run directory (recorder; saved sensor frames)")
      ->capture_default_str();
  return service::run_service("group", app, argc, argv, common, [&] {
    const auto s = service::load_scenario(common);
    std::set<std::string> seen;
    for (const auto& m : members) {
      if (!seen.insert(m).second) throw ConfigError("--member " + m + " given twice");
    }
    const auto dds = service::dds_options(common, s);
    if (!dds.security_dir.empty()) {
      // Permissions are per participant, and a group's members share one.
      throw ConfigError("DDS security needs one process per member (processes: per_member)");
    }
    const bool resume = !common.resume_from.empty() || common.rejoin;
    const record::RecorderOptions ro{output, dds.run_id, "distributed", resume};
    std::vector<proto::AgentPtr> agents;
    for (const auto& m : members) {
      agents.push_back(agents::make_agent(s, m, ro));
      if (s.checkpoint.enabled() || resume) agents::require_checkpoints(s, *agents.back());
    }

    // Once every member's outcome is settled, a Fast DDS abort while the run's participants
    // leave (a known 2.9.1 assertion) must not turn the process's outcome into a crash.
    std::mutex outcome_mutex;
    std::vector<int> outcomes;
    std::optional<service::DdsTeardownGuard> leaving;
    auto participant = std::make_shared<sdds::Participant>(dds);
    // One grant reader for all members (each grant decoded once), and their dones of each
    // frame to the coordinator as one sample.
    std::shared_ptr<sdds::GrantHub> grants;
    std::shared_ptr<sdds::DoneBatch> batch;
    if (members.size() > 1) {
      grants = std::make_shared<sdds::GrantHub>(participant);
      batch = std::make_shared<sdds::DoneBatch>(participant);
    }
    std::vector<std::unique_ptr<sdds::MemberRuntime>> runtimes;
    for (std::size_t i = 0; i < agents.size(); ++i) {
      auto options = service::member_options(common, debug, s, members[i]);
      options.done_batch = batch;
      options.grant_hub = grants;
      options.on_outcome = [&](int code) {
        std::lock_guard lock(outcome_mutex);
        outcomes.push_back(code);
        if (outcomes.size() == members.size()) leaving.emplace(combined_exit_code(outcomes));
      };
      runtimes.push_back(
          std::make_unique<sdds::MemberRuntime>(*agents[i], std::move(options), participant));
    }
    // One member's DDS entities after another (see MemberRuntime::prepare), then the frames.
    for (auto& r : runtimes) r->prepare();
    std::vector<int> codes(runtimes.size(), sdds::kExitFailed);
    {
      std::vector<std::thread> threads;
      for (std::size_t i = 0; i < runtimes.size(); ++i) {
        threads.emplace_back([&, i] {
          try {
            codes[i] = runtimes[i]->run(service::interrupted());
          } catch (const std::exception& e) {
            spdlog::error("{}: failed: {}", members[i], e.what());
            codes[i] = sdds::kExitFailed;
            if (batch) {
              try {
                batch->leave(members[i]);
              } catch (const std::exception&) {
              }
            }
          }
        });
      }
      for (auto& t : threads) t.join();
    }
    for (std::size_t i = 0; i < runtimes.size(); ++i) {
      if (codes[i] == sdds::kExitCompleted) {
        spdlog::info("{}: run completed", members[i]);
      } else {
        spdlog::error("{}: run ended: {}", members[i], runtimes[i]->end_reason());
      }
    }
    const int code = combined_exit_code(codes);
    {
      service::DdsTeardownGuard guard(code);
      for (auto& r : runtimes) r->close();
      runtimes.clear();  // they hold the hub and the batch, all of them the participant
      grants.reset();
      batch.reset();
      participant.reset();
    }
    return code;
  });
}
