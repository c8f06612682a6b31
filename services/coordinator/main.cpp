// syndds_coordinator: the time barrier of a run. See docs/protocol.md.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <optional>

#include "common/service_cli.hpp"
#include "dds/participant.hpp"
#include "core/error.hpp"
#include "dds/coordinator_service.hpp"
#include "record/checkpoint.hpp"

namespace service = syndds::service;
namespace sdds = syndds::dds;

int main(int argc, char** argv) {
  CLI::App app{"syndds coordinator: grants frames to the members a scenario declares"};
  service::CommonArgs common;
  service::add_common_options(app, common);
  bool print_members = false;
  app.add_flag("--print-members", print_members,
               "Print the member ids the scenario declares and exit");
  int exit_notice_delay_ms = 0;
  app.add_option("--debug-exit-notice-delay-ms", exit_notice_delay_ms,
                 "Act on a member's process exit this much later (fault injection; also "
                 "SYNDDS_DEBUG_EXIT_NOTICE_DELAY_MS, for runs started by the launcher)")
      ->group("Testing (fault injection; never needed in normal runs)")
      ->check(CLI::Range(0, 60000));
  return service::run_service("coordinator", app, argc, argv, common, [&] {
    const auto s = service::load_scenario_config(common);
    if (print_members) {
      for (const auto& m : s.member_ids()) std::printf("%s\n", m.c_str());
      return 0;
    }
    sdds::CoordinatorOptions o;
    o.dds = service::dds_options(common, s);
    o.dds.identity = "coordinator";
    o.config_fingerprint = s.fingerprint;
    o.config_files = syndds::fingerprint_lines(s.files);
    o.scenario_name = s.name;
    if (const char* env = std::getenv("SYNDDS_DEBUG_EXIT_NOTICE_DELAY_MS");
        env != nullptr && exit_notice_delay_ms == 0) {
      exit_notice_delay_ms = std::clamp(std::atoi(env), 0, 60000);
    }
    o.debug_exit_notice_delay_s = exit_notice_delay_ms / 1000.0;
    o.run_dir = common.run_dir;
    if (!common.run_dir.empty()) {
      // Beside the launcher's files: it is the run's operational state, not a result.
      o.status_file = (std::filesystem::path(common.run_dir) / "logs" / "run_status.json").string();
    }
    o.barrier.checkpoint_every = s.checkpoint.every_frames;
    o.checkpoint_keep_last = s.checkpoint.keep_last;
    if (s.checkpoint.enabled() && common.run_dir.empty()) {
      throw syndds::ConfigError(s.file + ": checkpoint: every_s is set; give the run directory "
                                "the checkpoints go to with --run-dir");
    }
    // A resumed run waits for every member of its checkpoint (late joiners that were in it
    // included) and starts with the frame after it.
    std::vector<std::string> resumed;
    if (!common.resume_from.empty()) {
      const std::int64_t frame = service::resume_frame(common, common.run_dir);
      const auto info = syndds::record::read_checkpoint_info(common.run_dir, frame);
      if (info.fingerprint != s.fingerprint) {
        throw syndds::ConfigError("--resume-from " + std::to_string(frame) +
                                  ": the checkpoint was written for another scenario or other "
                                  "overrides (fingerprint differs)");
      }
      for (const auto& m : info.members) resumed.push_back(m.member_id);
      o.barrier.first_frame = frame + 1;
      spdlog::info("coordinator: resuming from the checkpoint of frame {} ({} members)", frame,
                   resumed.size());
    }
    for (const auto& m : s.member_ids()) {
      const bool was_in = std::find(resumed.begin(), resumed.end(), m) != resumed.end();
      (s.is_late_member(m) && !was_in ? o.barrier.late_members : o.barrier.members).push_back(m);
    }
    o.barrier.final_frame = s.time.final_frame();
    o.barrier.heartbeat_s = s.time.heartbeat_s;
    o.barrier.join_timeout_s = s.coordinator.join_timeout_s;
    o.barrier.frame_timeout_s = s.coordinator.frame_timeout_s;
    o.barrier.on_member_loss = s.coordinator.on_member_loss;
    o.barrier.max_recoveries = s.coordinator.max_recoveries;
    o.barrier.rejoin_timeout_s = s.coordinator.rejoin_timeout_s;
    o.barrier.realtime = s.time.realtime;
    // From the verdict on, the members leave; Fast DDS 2.9.1 may abort on an assertion while
    // many participants leave at once (seen at 32 vehicles after a completed run), which must
    // not turn a finished run into a failed one.
    std::optional<service::DdsTeardownGuard> leaving;
    o.on_verdict = [&](int code) { leaving.emplace(code); };
    sdds::CoordinatorService coordinator(o);
    const int code = coordinator.run(service::interrupted());
    {
      service::DdsTeardownGuard guard(code);
      coordinator.close();
    }
    return code;
  });
}
