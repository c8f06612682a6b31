#include "dds/member_runtime.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <thread>

#include "core/error.hpp"
#include "dds/convert.hpp"
#include "protocol/local_runner.hpp"

namespace syndds::dds {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kPollInterval = std::chrono::milliseconds(50);  // for signals only

Clock::time_point after(double seconds) {
  return Clock::now() + std::chrono::duration_cast<Clock::duration>(
                            std::chrono::duration<double>(seconds));
}

template <typename W, typename Samples>
void write_all(W& writer, const Samples& samples, const char* topic, const std::string& key) {
  for (const auto& s : samples) {
    if (!writer) {
      throw ProtocolError(std::string("agent wrote ") + topic + " but did not declare it");
    }
    if (s.vehicle_id != key) {
      throw ProtocolError(std::string("agent wrote ") + topic + " for vehicle '" + s.vehicle_id +
                          "'; its samples must be about vehicle '" + key + "'");
    }
    if (!writer->write(to_dds(s))) {
      throw std::runtime_error(std::string("DDS refused a ") + topic + " sample");
    }
  }
}

// Interoceptive sensors may write several samples per key and frame (an IMU at the dynamics
// rate): their writers keep a deeper history.
const char* writer_profile(proto::Topic t) {
  switch (t) {
    case proto::Topic::gps_fix:
    case proto::Topic::imu:
    case proto::Topic::magnetometer:
    case proto::Topic::wheel_speeds:
      return profiles::kSensorWriter;
    default:
      return profiles::kDataWriter;
  }
}

}  // namespace

MemberRuntime::MemberRuntime(proto::Agent& agent, MemberRuntimeOptions options)
    : agent_(agent), options_(std::move(options)), inbox_(agent.subscriptions()) {}

MemberRuntime::~MemberRuntime() { close(); }

void MemberRuntime::close() {
  // Stop every DDS callback into this object before its members go: the lost-participant
  // callback, then the readers, then the writers, and the participant last.
  {
    std::unique_lock lock(mutex_);
    stop_frames(lock);
  }
  if (participant_) participant_->set_lost_callback(nullptr);
  announce_reader_.reset();
  grant_reader_.reset();
  control_reader_.reset();
  std::apply([](auto&... r) { (r.reset(), ...); }, data_readers_);
  announce_writer_.reset();
  done_writer_.reset();
  std::apply([](auto&... w) { (w.reset(), ...); }, data_writers_);
  participant_.reset();
}

void MemberRuntime::setup() {
  participant_ = std::make_unique<Participant>(options_.dds);
  participant_->set_lost_callback([this](const std::string& guid, bool graceful) {
    std::lock_guard lock(mutex_);
    if (coordinator_ && coordinator_->participant_guid == guid) {
      coordinator_lost_ = true;
      cv_.notify_all();
    }
  });

  // Readers before writers and before the announcement, so nothing addressed to us is missed.
  // A malformed sample (protocol or data) ends this member with the reason: dropping it would
  // only turn into a timeout later that names the wrong cause.
  auto guard = [this](const char* topic, auto&& fn) {
    try {
      fn();
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex_);
      if (failure_.empty()) {
        failure_ = std::string("received a malformed ") + topic + " sample: " + e.what();
      }
      cv_.notify_all();
    }
  };
  announce_reader_ = participant_->make_reader<msg::MemberAnnounce>(
      topics::kMemberAnnounce, profiles::kProtocolReader,
      [this, guard](msg::MemberAnnounce&& m, const fdds::SampleInfo& info) {
        guard("member_announce", [&] {
          auto a = from_dds(m);
          std::lock_guard lock(mutex_);
          note_announcement(a, writer_prefix(info));
          if (a.kind != proto::MemberKind::coordinator) return;
          if (!coordinator_) {
            coordinator_ = std::move(a);
          } else if (coordinator_->participant_guid != a.participant_guid && failure_.empty()) {
            failure_ = "a second coordinator (pid " + std::to_string(a.pid) + " on " + a.host +
                       ") announced run '" + a.run_id + "'";
          }
          cv_.notify_all();
        });
      });
  grant_reader_ = participant_->make_reader<msg::FrameGrant>(
      topics::kFrameGrant, profiles::kProtocolReader, [this, guard](msg::FrameGrant&& m) {
        guard("frame_grant", [&] {
          auto g = from_dds(m);
          std::unique_lock lock(mutex_);
          grants_.push_back(std::move(g));
          cv_.notify_all();
        });
      });
  control_reader_ = participant_->make_reader<msg::RunControl>(
      topics::kRunControl, profiles::kProtocolReader, [this, guard](msg::RunControl&& m) {
        guard("run_control", [&] {
          auto c = from_dds(m);
          std::lock_guard lock(mutex_);
          control_ = std::move(c);
          cv_.notify_all();
        });
      });

  auto subscribes = [this](proto::Topic t) {
    for (const auto& s : agent_.subscriptions()) {
      if (s.topic == t) return true;
    }
    return false;
  };
  // The one key all of the agent's subscriptions to a topic ask for ("" if any asks for all).
  auto only_key = [this](proto::Topic t) {
    std::string key;
    for (const auto& s : agent_.subscriptions()) {
      if (s.topic != t) continue;
      if (s.key.empty() || (!key.empty() && key != s.key)) return std::string();
      key = s.key;
    }
    return key;
  };
  const auto publications = agent_.publications();
  proto::for_each_topic([&](auto t) {
    constexpr proto::Topic T = decltype(t)::value;
    using Dds = typename DdsType<T>::type;
    const std::string name = topics::data(T);
    if (subscribes(T)) {
      std::get<static_cast<std::size_t>(T)>(data_readers_) = participant_->make_reader<Dds>(
          name, profiles::kDataReader, [this, guard](Dds&& m, const fdds::SampleInfo& info) {
            guard(proto::TopicTraits<T>::name, [&] {
              auto s = from_dds(m);
              std::unique_lock lock(mutex_);
              admit_locked<T>(std::move(s), writer_prefix(info));
            });
          },
          only_key(T).empty() ? Participant::Scope::all_vehicles : Participant::Scope::one_vehicle,
          only_key(T));
    }
    if (std::find(publications.begin(), publications.end(), T) != publications.end()) {
      std::get<static_cast<std::size_t>(T)>(data_writers_) =
          participant_->make_writer<Dds>(name, writer_profile(T), agent_.vehicle_key());
    }
  });
  done_writer_ = participant_->make_writer<msg::FrameDone>(topics::kFrameDone,
                                                          profiles::kProtocolWriter);
  announce_writer_ = participant_->make_writer<msg::MemberAnnounce>(topics::kMemberAnnounce,
                                                                    profiles::kProtocolWriter);
}

void MemberRuntime::note_announcement(const proto::MemberAnnounceMsg& a,
                                      const GuidPrefix& writer) {
  // An announcement names its participant; it counts only if that participant wrote it.
  GuidPrefix named;
  if (!parse_guid_prefix(a.participant_guid, named) || named != writer) {
    spdlog::error("{}: ignored the announcement of '{}': it names participant '{}' but was "
                  "written by {}", agent_.member_id(), a.member_id, a.participant_guid,
                  to_string(writer));
    return;
  }
  const auto [it, inserted] = members_.emplace(a.member_id, named);
  if (!inserted && it->second != named) {
    spdlog::error("{}: participant {} (pid {} on {}) announced itself as '{}', which participant "
                  "{} announced first: its samples are refused", agent_.member_id(),
                  a.participant_guid, a.pid, a.host, a.member_id, to_string(it->second));
    return;
  }
  if (!inserted) return;
  // Samples that arrived before their writer's announcement: decide now.
  std::vector<std::function<void()>> waiting;
  waiting.swap(unannounced_);
  for (auto& retry : waiting) retry();
}

template <proto::Topic T>
void MemberRuntime::admit_locked(typename proto::TopicTraits<T>::Msg sample,
                                 const GuidPrefix& writer) {
  const auto it = members_.find(sample.source);
  if (it == members_.end()) {
    // Its writer's announcement has not arrived yet (different writers are not ordered):
    // park the sample until it does. A sample whose source never announces itself stays
    // parked and is never used; the data barrier then names what is missing. Bounded: a
    // participant flooding samples under names nobody announced cannot grow this forever.
    constexpr std::size_t kMaxParked = 4096;
    if (unannounced_.size() >= kMaxParked) {
      spdlog::warn("{}: {} samples wait for members that never announced themselves; dropping "
                   "the oldest", agent_.member_id(), unannounced_.size());
      unannounced_.erase(unannounced_.begin(), unannounced_.begin() + kMaxParked / 2);
    }
    unannounced_.push_back([this, s = std::move(sample), writer]() mutable {
      admit_locked<T>(std::move(s), writer);
    });
    return;
  }
  if (it->second != writer) {
    proto::RejectedSample r;
    r.topic = T;
    r.key = sample.vehicle_id;
    r.source = sample.source;
    r.frame = sample.frame;
    r.writer = to_string(writer);
    r.reason = "written by participant " + r.writer + ", not by " + sample.source +
               " (participant " + to_string(it->second) + ")";
    spdlog::warn("{}: refused a {} sample for vehicle '{}' stamped frame {}: {}",
                 agent_.member_id(), proto::TopicTraits<T>::name, r.key, r.frame, r.reason);
    rejected_.push_back(std::move(r));
    return;
  }
  if (inbox_.add<T>(std::move(sample))) cv_.notify_all();
}

void MemberRuntime::announce() {
  proto::MemberAnnounceMsg a;
  a.member_id = agent_.member_id();
  a.kind = agent_.kind();
  a.run_id = options_.dds.run_id;
  a.participant_guid = participant_->guid_prefix();
  a.host = host_name();
  a.pid = process_id();
  a.config_fingerprint = options_.config_fingerprint;
  announce_writer_->write(to_dds(a));
}

bool MemberRuntime::wait_for_coordinator(const std::atomic<bool>& interrupt) {
  const auto deadline = after(options_.join_timeout_s);
  std::unique_lock lock(mutex_);
  while (!coordinator_) {
    if (interrupt.load()) {
      end_reason_ = "interrupted";
      return false;
    }
    if (Clock::now() >= deadline) {
      end_reason_ = "no coordinator for run '" + options_.dds.run_id + "' on DDS domain " +
                    std::to_string(options_.dds.domain_id) + " within " +
                    std::to_string(static_cast<int>(options_.join_timeout_s)) + " s";
      return false;
    }
    cv_.wait_for(lock, kPollInterval);
  }
  const auto& c = *coordinator_;
  const auto& expected = c.expected_members;
  if (std::find(expected.begin(), expected.end(), agent_.member_id()) == expected.end()) {
    end_reason_ = "the coordinator of run '" + options_.dds.run_id + "' does not expect member " +
                  agent_.member_id();
    return false;
  }
  if (c.config_fingerprint != options_.config_fingerprint) {
    end_reason_ = "scenario mismatch: the coordinator (host " + c.host +
                  ") loaded a different scenario or overrides (fingerprint " +
                  std::to_string(c.config_fingerprint) + ", mine " +
                  std::to_string(options_.config_fingerprint) + ")";
    return false;
  }
  if (c.protocol_version != proto::kProtocolVersion) {
    end_reason_ = "protocol version mismatch: coordinator " + std::to_string(c.protocol_version) +
                  ", mine " + std::to_string(proto::kProtocolVersion);
    return false;
  }
  return true;
}

bool MemberRuntime::wait_inputs(std::int64_t frame, const proto::Manifest& manifest,
                                double timeout_s, const std::atomic<bool>& interrupt) {
  const auto deadline = after(timeout_s);
  std::unique_lock lock(mutex_);
  while (!inbox_.complete(frame, manifest)) {
    if (interrupt.load() || coordinator_lost_ || (control_ && frame >= 0 &&
                                                  control_->final_frame < frame)) {
      return false;
    }
    if (Clock::now() >= deadline) return false;
    cv_.wait_until(lock, std::min(deadline, Clock::now() + kPollInterval));
  }
  return true;
}

bool MemberRuntime::flush_writers(double timeout_s) {
  bool all = true;
  auto flush = [&](auto& w) {
    if (w && !w->wait_for_acknowledgments(timeout_s)) all = false;
  };
  std::apply([&](auto&... w) { (flush(w), ...); }, data_writers_);
  return all;
}

void MemberRuntime::publish(const proto::FrameSamples& out) {
  proto::for_each_topic([&](auto t) {
    constexpr proto::Topic T = decltype(t)::value;
    write_all(std::get<static_cast<std::size_t>(T)>(data_writers_), out.list<T>(),
              proto::TopicTraits<T>::name, agent_.vehicle_key());
  });
}

void MemberRuntime::send_done(std::int64_t frame, const proto::Manifest& published,
                              double compute_s, bool finished) {
  proto::FrameDoneMsg d;
  d.member_id = agent_.member_id();
  d.frame = frame;
  d.published = published;
  d.compute_s = compute_s;
  d.finished = finished;
  if (!done_writer_->write(to_dds(d))) throw std::runtime_error("DDS refused a frame_done sample");
}

void MemberRuntime::stop_frames(std::unique_lock<std::mutex>& lock) {
  stopping_ = true;
  while (stepping_) cv_.wait_for(lock, kPollInterval);
}

int MemberRuntime::finish(const proto::RunControlMsg& announced,
                          const std::atomic<bool>& interrupt) {
  proto::RunControlMsg control = announced;
  proto::FrameSamples final_inputs;
  int code = control.status == proto::RunStatus::completed ? kExitCompleted : kExitAborted;
  bool already_taken = false;
  {
    std::lock_guard lock(mutex_);
    already_taken = control.final_frame <= inbox_.last_taken_frame();
  }
  if (control.final_frame >= 0 && !control.final_manifest.empty() && !already_taken) {
    const bool complete = wait_inputs(control.final_frame, control.final_manifest,
                                      options_.final_timeout_s, interrupt);
    std::lock_guard lock(mutex_);
    if (complete) {
      final_inputs = inbox_.take(control.final_frame, control.final_manifest);
    } else {
      // Never hand out a partial frame: the agent ends with the last complete one, and says so.
      const std::string missing =
          inbox_.describe_missing(control.final_frame, control.final_manifest);
      spdlog::error("{}: final frame {} incomplete, not used: {}", agent_.member_id(),
                    control.final_frame, missing);
      control.status = proto::RunStatus::aborted;
      control.reason = (control.reason.empty() ? "" : control.reason + "; ") + "final frame " +
                       std::to_string(control.final_frame) + " incomplete at " +
                       agent_.member_id() + ": " + missing;
      code = kExitFailed;
    }
  }
  agent_.finish(proto::RunEnd{control}, final_inputs);
  if (end_reason_.empty()) end_reason_ = control.reason;
  try {
    // Whatever this member wrote must reach its readers before the process (and its shared
    // memory segments) goes away: a sample still in flight when the writer disappears is lost.
    if (!flush_writers(2.0)) {
      spdlog::warn("{}: not every reader acknowledged this member's last samples within 2 s",
                   agent_.member_id());
    }
    send_done(control.final_frame, {}, 0.0, true);
    done_writer_->wait_for_acknowledgments(2.0);
  } catch (const std::exception& e) {
    spdlog::warn("{}: could not confirm the end of the run: {}", agent_.member_id(), e.what());
  }
  return code;
}

// True when pump_locked() has something to do with the first queued grant.
bool MemberRuntime::frame_ready_locked() const {
  if (grants_.empty()) return false;
  const proto::FrameGrantMsg& g = grants_.front();
  if (!admitted_ || g.frame != next_frame_) return true;  // to skip, or a protocol error
  return options_.debug_skip_data_barrier || inbox_.complete(g.frame - 1, g.manifest);
}

// Runs every granted frame whose inputs are complete (in the main thread). One frame runs at a
// time (stepping_); called with mutex_ held, released while the agent steps.
void MemberRuntime::pump_locked(std::unique_lock<std::mutex>& lock) {
  while (ready_ && !stepping_ && !stopping_ && !control_ && failure_.empty() &&
         !grants_.empty()) {
    proto::FrameGrantMsg& front = grants_.front();
    if (!admitted_) {
      // A late joiner starts with the frame after the grant that names it; grants before that
      // (also old ones replayed by TRANSIENT_LOCAL) are not its business.
      const auto& j = front.joiners;
      if (std::find(j.begin(), j.end(), agent_.member_id()) != j.end()) {
        admitted_ = true;
        next_frame_ = front.frame + 1;
        spdlog::info("{}: admitted; taking part from frame {}", agent_.member_id(), next_frame_);
      }
      grants_.pop_front();
      continue;
    }
    if (front.frame < next_frame_) {  // duplicate
      grants_.pop_front();
      continue;
    }
    if (front.frame > next_frame_) {
      failure_ = "protocol error: granted frame " + std::to_string(front.frame) +
                 " while frame " + std::to_string(next_frame_) + " was expected";
      cv_.notify_all();
      return;
    }
    const std::int64_t input_frame = front.frame - 1;
    if (!options_.debug_skip_data_barrier && !inbox_.complete(input_frame, front.manifest)) {
      return;  // the data barrier: the callback storing the last announced sample wakes us
    }
    proto::FrameGrantMsg grant = std::move(front);
    grants_.pop_front();
    proto::FrameSamples inputs = inbox_.take(input_frame, grant.manifest);
    std::vector<proto::RejectedSample> rejected;
    rejected.swap(rejected_);
    stepping_ = true;
    lock.unlock();
    std::string error;
    try {
      if (!rejected.empty()) agent_.note_rejected(rejected);
      run_frame(grant, inputs);
    } catch (const std::exception& e) {
      error = "frame " + std::to_string(grant.frame) + ": " + e.what();
    }
    lock.lock();
    stepping_ = false;
    next_frame_ = grant.frame + 1;
    if (!error.empty()) failure_ = error;
    cv_.notify_all();
  }
}

void MemberRuntime::run_frame(const proto::FrameGrantMsg& grant,
                              const proto::FrameSamples& inputs) {
  const auto t0 = Clock::now();
  proto::FrameSamples outputs;
  const proto::FrameContext ctx{grant.frame, grant.sim_time_s, options_.heartbeat_s,
                                grant.joiners};
  agent_.step(ctx, inputs, outputs);
  proto::check_outputs(outputs, grant.frame, agent_.member_id(), agent_.vehicle_key());
  if (options_.debug_frame_delay_ms > 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.debug_frame_delay_ms));
  }
  const double compute_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const proto::Manifest published = outputs.manifest(agent_.member_id());
  if (options_.debug_publish_delay_ms > 0) {
    send_done(grant.frame, published, compute_s, false);
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.debug_publish_delay_ms));
    publish(outputs);
  } else {
    publish(outputs);
    send_done(grant.frame, published, compute_s, false);
  }
}

int MemberRuntime::run(const std::atomic<bool>& interrupt) {
  auto local_abort = [&](const std::string& reason, int code) {
    end_reason_ = reason;
    if (code == kExitFailed && done_writer_) {
      // Tell the coordinator why, so the run's one-line reason names the cause.
      try {
        proto::FrameDoneMsg d;
        d.member_id = agent_.member_id();
        d.frame = next_frame_;
        d.error = reason;
        done_writer_->write(to_dds(d));
        done_writer_->wait_for_acknowledgments(1.0);
      } catch (const std::exception&) {
      }
    }
    proto::RunControlMsg c;
    c.status = proto::RunStatus::aborted;
    c.reason = reason;
    agent_.finish(proto::RunEnd{c}, {});
    return code;
  };

  setup();
  announce();
  spdlog::info("{}: announced; waiting for the coordinator of run '{}' on domain {}",
               agent_.member_id(), options_.dds.run_id, options_.dds.domain_id);
  if (!wait_for_coordinator(interrupt)) {
    return local_abort(end_reason_, interrupt.load() ? kExitInterrupted : kExitFailed);
  }
  {
    std::lock_guard lock(mutex_);
    spdlog::info("{}: joined run '{}' (coordinator on {})", agent_.member_id(),
                 options_.dds.run_id, coordinator_->host);
  }

  // This thread runs the frames (pump_locked) and watches for the end, failures and deadlines.
  // DDS callbacks only store what arrives and wake it: a long frame must not block a DDS thread
  // (it would hold Fast DDS's internal locks, delay acknowledgements, even liveliness).
  std::unique_lock lock(mutex_);
  ready_ = true;
  admitted_ = !options_.late_join;
  std::int64_t waiting_frame = -1;
  auto waiting_since = Clock::now();
  while (true) {
    cv_.wait_for(lock, kPollInterval, [&] {
      return control_ || !failure_.empty() || coordinator_lost_ || interrupt.load() ||
             frame_ready_locked();
    });
    // Every way out first stops frames from starting in DDS threads (and waits for one that
    // runs): the agent's finish() must never overlap a step.
    if (control_) {
      const proto::RunControlMsg control = *control_;
      stop_frames(lock);
      lock.unlock();
      return finish(control, interrupt);
    }
    if (!failure_.empty()) {
      const std::string failure = failure_;
      stop_frames(lock);
      lock.unlock();
      return local_abort(failure, kExitFailed);
    }
    if (interrupt.load()) {
      stop_frames(lock);
      lock.unlock();
      return local_abort("interrupted", kExitInterrupted);
    }
    if (coordinator_lost_) {
      stop_frames(lock);
      lock.unlock();
      return local_abort("the coordinator was lost (its process exited or stopped answering)",
                         kExitFailed);
    }
    pump_locked(lock);
    // A granted frame whose announced inputs do not arrive in time.
    if (grants_.empty()) {
      waiting_frame = -1;
      continue;
    }
    const proto::FrameGrantMsg& grant = grants_.front();
    if (grant.frame != waiting_frame) {
      waiting_frame = grant.frame;
      waiting_since = Clock::now();
    } else if (std::chrono::duration<double>(Clock::now() - waiting_since).count() >
               options_.input_timeout_s) {
      const std::int64_t frame = grant.frame;
      const std::string missing = inbox_.describe_missing(frame - 1, grant.manifest);
      stop_frames(lock);
      lock.unlock();
      return local_abort("frame " + std::to_string(frame) +
                             ": announced inputs missing after " +
                             fmt::format("{:g}", options_.input_timeout_s) + " s: " + missing,
                         kExitFailed);
    }
  }
}

}  // namespace syndds::dds
