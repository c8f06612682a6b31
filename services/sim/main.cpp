// syndds_sim: every agent of a scenario in one process, with the same frame semantics as the
// distributed run (the recorded results are byte-identical). For debugging, training and
// determinism checks. Writes checkpoints when the scenario asks (checkpoint: every_s) and
// resumes from one (--resume-from), with the same files as a distributed run.
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>

#include "agents/agent_factory.hpp"
#include "common/service_cli.hpp"
#include "core/error.hpp"
#include "dds/member_runtime.hpp"
#include "learn/register_policy_controller.hpp"
#include "protocol/local_runner.hpp"
#include "record/checkpoint.hpp"

using namespace syndds;
namespace sdds = syndds::dds;

int main(int argc, char** argv) {
  learn::register_policy_controller();
  CLI::App app{"syndds single-process runner: all agents of a scenario in one process"};
  service::CommonArgs common;
  service::add_common_options(app, common);
  std::string output = "runs/latest";
  bool quiet = false;
  std::string checkpoint_log;
  app.add_option("--output", output, "Run directory")->capture_default_str();
  app.add_flag("--quiet", quiet, "Do not print the summary");
  app.add_option("--checkpoint-log", checkpoint_log,
                 "Write a CSV row per member and checkpoint here (frame, sim_time_s, member, "
                 "bytes, write_ms: the wall time to save and write its file)");
  return service::run_service("sim", app, argc, argv, common, [&] {
    const auto s = service::load_scenario(common);
    const std::string run_id = service::dds_options(common, s).run_id;  // validated
    const std::string run_dir = common.run_dir.empty() ? output : common.run_dir;
    const bool resume = !common.resume_from.empty();
    const std::int64_t resume_at = resume ? service::resume_frame(common, run_dir) : -1;
    auto agents = agents::make_all_agents(
        s, record::RecorderOptions{output, run_id, "single-process", resume});
    if (s.checkpoint.enabled() || resume) {
      for (const auto& a : agents) agents::require_checkpoints(s, *a);
    }
    proto::LocalRunner runner(std::move(agents),
                              {s.time.final_frame(), s.time.heartbeat_s, s.time.realtime});
    std::ofstream timings;
    if (!checkpoint_log.empty()) {
      timings.open(checkpoint_log);
      if (!timings) throw ConfigError("--checkpoint-log: cannot write " + checkpoint_log);
      timings << "frame,sim_time_s,member,bytes,write_ms\n";
    }
    if (s.checkpoint.enabled()) {
      runner.set_after_frame([&](proto::FrameStepper& stepper) {
        const std::int64_t frame = stepper.next_frame() - 1;
        // As distributed: the checkpoint of frame K is written before frame K + 1 (none of the
        // final frame).
        if (!record::checkpoint_due(frame, s.checkpoint.every_frames) ||
            frame >= s.time.final_frame()) {
          return;
        }
        const auto info = record::write_local_checkpoint(run_dir, stepper, s.fingerprint,
                                                         s.time.heartbeat_s);
        std::uint64_t bytes = 0;
        double seconds = 0.0;
        for (const auto& m : info.members) {
          bytes += m.bytes;
          seconds += m.write_s;
          spdlog::debug("checkpoint of frame {}: {} {} bytes {:.3f} ms", frame, m.member_id,
                        m.bytes, 1e3 * m.write_s);
          if (timings.is_open()) {
            timings << fmt::format("{},{:g},{},{},{:.3f}\n", frame, info.sim_time_s, m.member_id,
                                   m.bytes, 1e3 * m.write_s)
                    << std::flush;
          }
        }
        spdlog::info("checkpoint of frame {} (t = {:g} s): {} members, {} bytes, {:.1f} ms",
                     frame, info.sim_time_s, info.members.size(), bytes, 1e3 * seconds);
        try {
          record::prune_checkpoints(run_dir, frame, s.checkpoint.keep_last);
        } catch (const std::exception& e) {
          spdlog::warn("old checkpoints: {}", e.what());
        }
      });
    }
    if (resume) {
      record::resume_local(run_dir, resume_at, s.fingerprint, runner.stepper());
      spdlog::info("resumed from the checkpoint of frame {} in {}", resume_at, run_dir);
    }
    const auto end = runner.run(&service::interrupted());
    if (!quiet && s.recorder.enabled) {
      std::ifstream summary(output + "/summary.txt");
      std::cout << summary.rdbuf();
    }
    return end.status == proto::RunStatus::completed ? sdds::kExitCompleted
                                                      : sdds::kExitInterrupted;
  });
}
