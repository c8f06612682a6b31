#include "protocol/local_runner.hpp"

#include <chrono>
#include <map>
#include <thread>

#include "core/error.hpp"
#include "protocol/contact_bodies.hpp"

namespace syndds::proto {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

template <typename T>
void check_list(const std::vector<T>& v, std::string_view topic, std::int64_t frame,
                const std::string& source, const std::string& key, std::uint32_t max_per_frame,
                bool addressed) {
  // The same limit as the DDS writer's history (TopicTraits::max_per_frame): a step that writes
  // more fails in one process exactly as it would distributed.
  std::map<std::string, std::uint32_t> per_key;
  for (const auto& s : v) {
    if (++per_key[addressed ? s.vehicle_id : key] > max_per_frame) {
      throw ProtocolError(source + " wrote more than " + std::to_string(max_per_frame) + " " +
                          std::string(topic) + " samples " +
                          (addressed ? "for vehicle '" + s.vehicle_id + "' " : std::string()) +
                          "in frame " + std::to_string(frame) + "; at most " +
                          std::to_string(max_per_frame) + " per vehicle and frame");
    }
  }
  for (const auto& s : v) {
    if (s.frame != frame || s.source != source) {
      throw ProtocolError(source + " wrote a " + std::string(topic) + " sample stamped frame " +
                          std::to_string(s.frame) + " source '" + s.source + "' in frame " +
                          std::to_string(frame));
    }
    if (addressed) {
      if (s.vehicle_id.empty()) {
        throw ProtocolError(source + " wrote a " + std::string(topic) +
                            " sample addressed to no vehicle");
      }
    } else if (s.vehicle_id != key) {
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
               TopicTraits<T>::max_per_frame, is_addressed(T));
  });
  if (out.contact_bodies.size() > 1) {
    throw ProtocolError(source + " reported " + std::to_string(out.contact_bodies.size()) +
                        " contact bodies in frame " + std::to_string(frame) + "; at most one");
  }
  for (const auto& b : out.contact_bodies) {
    if (b.vehicle_id != vehicle_key) {
      throw ProtocolError(source + " reported the contact body of vehicle '" + b.vehicle_id +
                          "'; it can only report '" + vehicle_key + "'");
    }
  }
}

FrameStepper::FrameStepper(std::vector<AgentPtr> agents, double heartbeat_s)
    : agents_(std::move(agents)), heartbeat_s_(heartbeat_s) {
  member_stats_.resize(agents_.size());
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    subs_.push_back(agents_[i]->subscriptions());
    member_stats_[i].member_id = agents_[i]->member_id();
  }
}

FrameSamples FrameStepper::next_inputs(std::size_t i) const {
  if (!resumed_inputs_.empty()) return resumed_inputs_.at(i);
  return previous_.filtered(subs_.at(i));
}

void FrameStepper::resume(std::int64_t completed_frame, std::vector<FrameSamples> next_inputs) {
  if (completed_ != -1 || finished_) throw ProtocolError("FrameStepper::resume after a step");
  if (next_inputs.size() != agents_.size()) {
    throw ProtocolError("FrameStepper::resume: " + std::to_string(next_inputs.size()) +
                        " input lists for " + std::to_string(agents_.size()) + " agents");
  }
  completed_ = completed_frame;
  resumed_inputs_ = std::move(next_inputs);
}

void FrameStepper::step() {
  if (finished_) throw ProtocolError("FrameStepper::step after the run ended");
  const std::int64_t frame = completed_ + 1;
  if (frame == 0 || !resumed_inputs_.empty()) t0_ = Clock::now();
  // Nobody joins late, departs or intrudes here: every agent lives (and fails) with this process.
  FrameContext ctx{frame, static_cast<double>(frame) * heartbeat_s_, heartbeat_s_, {}, {}, {}};
  FrameSamples current;
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    const auto step_t0 = Clock::now();
    FrameSamples inputs = next_inputs(i);
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
      control.final_frame = completed_;
      finished_ = true;
      for (std::size_t j = 0; j < agents_.size(); ++j) {
        agents_[j]->finish(RunEnd{control}, j > i ? next_inputs(j) : FrameSamples{});
      }
      throw;
    }
    current.append(outputs);
    member_stats_[i].mean_compute_s += seconds_since(step_t0);
  }
  // What the barrier does between frames: the bodies of vehicles within reach of another.
  current.contact_bodies = select_contact_bodies(std::move(current.contact_bodies), heartbeat_s_);
  current.sort();
  previous_ = std::move(current);
  resumed_inputs_.clear();
  completed_ = frame;
}

RunControlMsg FrameStepper::finish(RunStatus status, const std::string& reason) {
  if (finished_) throw ProtocolError("FrameStepper::finish twice");
  finished_ = true;
  RunControlMsg control;
  control.status = status;
  control.reason = reason;
  control.final_frame = completed_;
  control.final_manifest.clear();
  control.stats.frames = static_cast<std::uint64_t>(completed_ + 1);
  control.stats.final_frame = completed_;
  control.stats.sim_time_s = completed_ > 0 ? static_cast<double>(completed_) * heartbeat_s_ : 0.0;
  control.stats.wall_time_s = completed_ >= 0 ? seconds_since(t0_) : 0.0;
  control.stats.real_time_factor =
      control.stats.sim_time_s > 0 ? control.stats.wall_time_s / control.stats.sim_time_s : 0.0;
  for (auto& ms : member_stats_) {
    if (completed_ >= 0) ms.mean_compute_s /= static_cast<double>(completed_ + 1);
    ms.mean_response_s = ms.mean_compute_s;
  }
  control.stats.members = member_stats_;

  RunEnd end{control};
  for (std::size_t i = 0; i < agents_.size(); ++i) {
    agents_[i]->finish(end, next_inputs(i));
  }
  return control;
}

LocalRunner::LocalRunner(std::vector<AgentPtr> agents, LocalRunOptions options)
    : stepper_(std::move(agents), options.heartbeat_s), options_(options) {}

RunControlMsg LocalRunner::run(const std::atomic<bool>* interrupt) {
  const auto t0 = Clock::now();
  bool interrupted = false;
  const std::int64_t first = stepper_.next_frame();  // 0, or the frame after a checkpoint
  for (std::int64_t frame = first; frame <= options_.final_frame; ++frame) {
    if (interrupt && interrupt->load()) {
      interrupted = true;
      break;
    }
    if (options_.realtime) {
      std::this_thread::sleep_until(
          t0 + std::chrono::duration_cast<Clock::duration>(
                   std::chrono::duration<double>(static_cast<double>(frame - first) *
                                                 options_.heartbeat_s)));
    }
    stepper_.step();
    if (after_frame_) after_frame_(stepper_);
  }
  return stepper_.finish(interrupted ? RunStatus::aborted : RunStatus::completed,
                        interrupted ? "interrupted" : "");
}

}  // namespace syndds::proto
