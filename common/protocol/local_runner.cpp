#include "protocol/local_runner.hpp"

#include <chrono>
#include <thread>

#include "core/error.hpp"

namespace syndds::proto {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

template <typename T>
void check_list(const std::vector<T>& v, std::string_view topic, std::int64_t frame,
                const std::string& source, const std::string& key, std::uint32_t max_per_frame) {
  // The same limit as the DDS writer's history (TopicTraits::max_per_frame): a step that writes
  // more fails in one process exactly as it would distributed.
  if (v.size() > max_per_frame) {
    throw ProtocolError(source + " wrote " + std::to_string(v.size()) + " " + std::string(topic) +
                        " samples in frame " + std::to_string(frame) + "; at most " +
                        std::to_string(max_per_frame) + " per vehicle and frame");
  }
  for (const auto& s : v) {
    if (s.frame != frame || s.source != source) {
      throw ProtocolError(source + " wrote a " + std::string(topic) + " sample stamped frame " +
                          std::to_string(s.frame) + " source '" + s.source + "' in frame " +
                          std::to_string(frame));
    }
    if (s.vehicle_id != key) {
      throw ProtocolError(source + " wrote a " + std::string(topic) + " sample of vehicle '" +
                          s.vehicle_id + "'; its samples must be about '" + key + "'");
    }
  }
}

}  // namespace

void check_outputs(const FrameSamples& out, std::int64_t frame, const std::string& source,
                   const std::string& vehicle_key) {
  for_each_topic([&](auto t) {
    constexpr Topic T = decltype(t)::value;
    check_list(out.list<T>(), TopicTraits<T>::name, frame, source, vehicle_key,
               TopicTraits<T>::max_per_frame);
  });
}

LocalRunner::LocalRunner(std::vector<AgentPtr> agents, LocalRunOptions options)
    : agents_(std::move(agents)), options_(options) {}

RunControlMsg LocalRunner::run(const std::atomic<bool>* interrupt) {
  std::vector<std::vector<Subscription>> subs;
  std::vector<MemberStatsMsg> member_stats(agents_.size());
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    subs.push_back(agents_[i]->subscriptions());
    member_stats[i].member_id = agents_[i]->member_id();
  }

  const auto t0 = Clock::now();
  FrameSamples previous;  // everything stamped frame - 1
  std::int64_t completed = -1;
  bool interrupted = false;
  for (std::int64_t frame = 0; frame <= options_.final_frame; ++frame) {
    if (interrupt && interrupt->load()) {
      interrupted = true;
      break;
    }
    if (options_.realtime) {
      std::this_thread::sleep_until(
          t0 + std::chrono::duration_cast<Clock::duration>(
                   std::chrono::duration<double>(frame * options_.heartbeat_s)));
    }
    // Nobody joins late or departs here: every agent lives (and fails) with this process.
    FrameContext ctx{frame, static_cast<double>(frame) * options_.heartbeat_s,
                     options_.heartbeat_s, {}, {}};
    FrameSamples current;
    for (std::size_t i = 0; i < agents_.size(); ++i) {
      const auto step_t0 = Clock::now();
      FrameSamples inputs = previous.filtered(subs[i]);
      FrameSamples outputs;
      try {
        agents_[i]->step(ctx, inputs, outputs);
        check_outputs(outputs, frame, agents_[i]->member_id(), agents_[i]->vehicle_key());
      } catch (const std::exception& e) {
        // Every agent still learns how the run ended (the recorder writes its summary), and, as
        // in the distributed run, the last complete frame is not lost: the agents that have not
        // consumed its samples yet (not stepped in this frame) get them as final inputs.
        RunControlMsg control;
        control.status = RunStatus::aborted;
        control.reason = agents_[i]->member_id() + " failed in frame " + std::to_string(frame) +
                         ": " + e.what();
        control.final_frame = completed;
        for (std::size_t j = 0; j < agents_.size(); ++j) {
          agents_[j]->finish(RunEnd{control}, j > i ? previous.filtered(subs[j]) : FrameSamples{});
        }
        throw;
      }
      current.append(outputs);
      member_stats[i].mean_compute_s += seconds_since(step_t0);
    }
    current.sort();
    previous = std::move(current);
    completed = frame;
  }

  RunControlMsg control;
  control.status = interrupted ? RunStatus::aborted : RunStatus::completed;
  control.reason = interrupted ? "interrupted" : "";
  control.final_frame = completed;
  control.final_manifest.clear();
  control.stats.frames = static_cast<std::uint64_t>(completed + 1);
  control.stats.final_frame = completed;
  control.stats.sim_time_s = completed > 0 ? completed * options_.heartbeat_s : 0.0;
  control.stats.wall_time_s = seconds_since(t0);
  control.stats.real_time_factor =
      control.stats.sim_time_s > 0 ? control.stats.wall_time_s / control.stats.sim_time_s : 0.0;
  for (auto& ms : member_stats) {
    if (completed >= 0) ms.mean_compute_s /= static_cast<double>(completed + 1);
    ms.mean_response_s = ms.mean_compute_s;
  }
  control.stats.members = member_stats;

  RunEnd end{control};
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    agents_[i]->finish(end, previous.filtered(subs[i]));
  }
  return control;
}

}  // namespace syndds::proto
