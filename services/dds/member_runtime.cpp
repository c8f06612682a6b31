#include "dds/member_runtime.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <thread>

#include "core/build_identity.hpp"
#include "core/error.hpp"
#include "dds/convert.hpp"
#include "dds/done_batch.hpp"
#include "dds/grant_hub.hpp"
#include "protocol/admission.hpp"
#include "protocol/local_runner.hpp"
#include "record/checkpoint.hpp"

namespace syndds::dds {
namespace {

using Clock = std::chrono::steady_clock;
constexpr auto kPollInterval = std::chrono::milliseconds(50);  // for signals only

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

MemberRuntime::MemberRuntime(proto::Agent& agent, MemberRuntimeOptions options,
                             std::shared_ptr<Participant> shared)
    : agent_(agent), options_(std::move(options)), participant_(std::move(shared)) {}

MemberRuntime::~MemberRuntime() { close(); }

double MemberRuntime::now() const {
  return std::chrono::duration<double>(Clock::now() - t0_).count();
}

proto::MemberSessionConfig MemberRuntime::session_config() const {
  proto::MemberSessionConfig c;
  c.member_id = agent_.member_id();
  c.run_id = options_.dds.run_id;
  c.transport = "DDS domain " + std::to_string(options_.dds.domain_id);
  c.config_fingerprint = options_.config_fingerprint;
  c.heartbeat_s = options_.heartbeat_s;
  c.join_timeout_s = options_.join_timeout_s;
  c.input_timeout_s = options_.input_timeout_s;
  c.final_timeout_s = options_.final_timeout_s;
  c.interrupt_grace_s = options_.interrupt_grace_s;
  c.late_join = options_.late_join;
  c.skip_data_barrier = options_.debug_skip_data_barrier;
  c.resume_frame = options_.resume_frame;
  c.rejoin = options_.rejoin;
  c.participant_guid = participant_->guid_prefix();
  c.config_files = options_.config_files;
  c.build_id = options_.debug_build_id.empty() ? build_identity() : options_.debug_build_id;
  return c;
}

void MemberRuntime::close() {
  // Frames run in the thread of run(), so none runs any more. Stop every DDS callback into this
  // object before its members go: the lost-participant callback, then the readers, then the
  // writers, and the participant last.
  if (participant_ && lost_callback_ >= 0) participant_->remove_lost_callback(lost_callback_);
  lost_callback_ = -1;
  coordinator_watch_.stop();
  announce_reader_.reset();
  grant_reader_.reset();
  if (options_.grant_hub && grant_hub_id_ >= 0) options_.grant_hub->remove(grant_hub_id_);
  grant_hub_id_ = -1;
  control_reader_.reset();
  std::apply([](auto&... r) { (r.reset(), ...); }, data_readers_);
  announce_writer_.reset();
  done_writer_.reset();
  std::apply([](auto&... w) { (w.reset(), ...); }, data_writers_);
  patch_writers_.clear();
  participant_.reset();
}

void MemberRuntime::setup() {
  if (!participant_) participant_ = std::make_shared<Participant>(options_.dds);
  lost_callback_ = participant_->add_lost_callback([this](const std::string& guid, bool graceful) {
    std::lock_guard lock(mutex_);
    const auto& c = session_->coordinator();
    if (!c || c->participant_guid != guid) return;
    if (!graceful && coordinator_watch_.watching(c->process_key)) {
      // Its lease expired, but its process (on this machine) still runs: slow, not dead. Its
      // participant is found again when its announcements resume; its exit is seen at once.
      spdlog::warn("{}: the coordinator's DDS lease expired but its process is running "
                   "(overloaded or stopped?): waiting for it",
                   agent_.member_id());
      return;
    }
    session_->on_coordinator_lost(now());
    cv_.notify_all();
  });

  // Readers before writers and before the announcement, so nothing addressed to us is missed.
  // A malformed sample (protocol or data) ends this member with the reason: dropping it would
  // only turn into a timeout later that names the wrong cause.
  auto guard = [this](const char* topic, auto&& fn) {
    try {
      fn();
    } catch (const std::exception& e) {
      std::lock_guard lock(mutex_);
      session_->on_failure(std::string("received a malformed ") + topic + " sample: " + e.what(),
                           now());
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
          session_->on_coordinator(a, now());
          apply_admission_locked(*session_->coordinator());
          watch_coordinator_locked();
          cv_.notify_all();
        });
      });
  if (options_.grant_hub) {
    grant_hub_id_ = options_.grant_hub->add(
        [this](proto::FrameGrantMsg g, const proto::Manifest& manifest) {
          std::unique_lock lock(mutex_);
          session_->on_grant(std::move(g), manifest, now());
          cv_.notify_all();
        },
        [this](const std::string& why) {
          std::lock_guard lock(mutex_);
          session_->on_failure("received a malformed frame_grant sample: " + why, now());
          cv_.notify_all();
        });
  } else {
    grant_reader_ = participant_->make_reader<msg::FrameGrant>(
        topics::kFrameGrant, profiles::kProtocolReader, [this, guard](msg::FrameGrant&& m) {
          guard("frame_grant", [&] {
            auto g = from_dds(m);
            std::unique_lock lock(mutex_);
            session_->on_grant(std::move(g), now());
            cv_.notify_all();
          });
        });
  }
  control_reader_ = participant_->make_reader<msg::RunControl>(
      topics::kRunControl, profiles::kProtocolReader, [this, guard](msg::RunControl&& m) {
        guard("run_control", [&] {
          auto c = from_dds(m);
          std::lock_guard lock(mutex_);
          session_->on_control(std::move(c), now());
          cv_.notify_all();
        });
      });

  auto subscribes = [this](proto::Topic t) {
    for (const auto& s : agent_.subscriptions()) {
      if (s.topic == t) return true;
    }
    return false;
  };
  const auto publications = agent_.publications();
  proto::for_each_topic([&](auto t) {
    constexpr proto::Topic T = decltype(t)::value;
    using Dds = typename DdsType<T>::type;
    const std::string name = topics::data(T);
    if (subscribes(T)) {
      const auto keys = proto::subscribed_keys(agent_.subscriptions(), T);
      std::get<static_cast<std::size_t>(T)>(data_readers_) = participant_->make_reader<Dds>(
          name, profiles::kDataReader, [this, guard](Dds&& m, const fdds::SampleInfo& info) {
            guard(proto::TopicTraits<T>::name, [&] {
              auto s = from_dds(m);
              std::unique_lock lock(mutex_);
              admit_locked<T>(std::move(s), writer_prefix(info));
            });
          },
          // Matched only with the writers of the vehicles it needs (every vehicle's if any
          // subscription asks for all): no other vehicle's samples travel to this process.
          keys.empty() ? Participant::Scope::all_vehicles : Participant::Scope::these_vehicles,
          keys);
    }
    if (std::find(publications.begin(), publications.end(), T) != publications.end()) {
      if constexpr (proto::is_addressed(T)) {
        writes_patches_ = true;  // writers per destination, made on first use (publish)
        return;
      }
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
    // An impostor, or the member restarted (on_member_loss: recover): the coordinator's
    // rollback grant says which participant is the member from then on; until then its
    // samples wait.
    if (reannounced_[a.member_id].insert(named).second) {
      spdlog::warn("{}: participant {} (pid {} on {}) announced itself as '{}', which participant "
                   "{} announced first: its samples wait until the coordinator names it (a "
                   "restarted member) and are refused otherwise", agent_.member_id(),
                   a.participant_guid, a.pid, a.host, a.member_id, to_string(it->second));
    }
    return;
  }
  if (!inserted) return;
  // Samples that arrived before their writer's announcement: decide now.
  std::vector<std::function<void()>> waiting;
  waiting.swap(unannounced_);
  for (auto& retry : waiting) retry();
}

// The coordinator's word on who is which member wins over the order in which announcements
// arrived here: a claimant it refused has its samples refused (parked ones included), and a
// member first announced here by a claimant it refused is the participant it admitted.
void MemberRuntime::apply_admission_locked(const proto::MemberAnnounceMsg& coordinator) {
  bool changed = false;
  for (const auto& entry : coordinator.refused) {
    std::string member, participant;
    GuidPrefix guid;
    if (!proto::split_member_entry(entry, member, participant) ||
        !parse_guid_prefix(participant, guid)) {
      continue;
    }
    if (refused_[member].insert(guid).second) changed = true;
  }
  for (const auto& entry : coordinator.admitted) {
    std::string member, participant;
    GuidPrefix guid;
    if (!proto::split_member_entry(entry, member, participant) ||
        !parse_guid_prefix(participant, guid)) {
      continue;
    }
    const auto it = members_.find(member);
    if (it == members_.end() || it->second == guid) continue;
    const auto refused = refused_.find(member);
    if (refused != refused_.end() && refused->second.contains(it->second)) {
      it->second = guid;
      changed = true;
    }
  }
  if (!changed) return;
  std::vector<std::function<void()>> waiting;
  waiting.swap(unannounced_);
  for (auto& retry : waiting) retry();
}

void MemberRuntime::park_locked(std::function<void()> retry) {
  // A sample whose source never announces itself (or is never admitted) stays parked and is
  // never used; the data barrier then names what is missing. Bounded: a participant flooding
  // samples under names nobody announced cannot grow this forever.
  constexpr std::size_t kMaxParked = 4096;
  if (unannounced_.size() >= kMaxParked) {
    spdlog::warn("{}: {} samples wait for members that never announced themselves or were not "
                 "admitted yet; dropping the oldest", agent_.member_id(), unannounced_.size());
    unannounced_.erase(unannounced_.begin(), unannounced_.begin() + kMaxParked / 2);
  }
  unannounced_.push_back(std::move(retry));
}

template <proto::Topic T>
void MemberRuntime::admit_locked(typename proto::TopicTraits<T>::Msg sample,
                                 const GuidPrefix& writer) {
  const auto it = members_.find(sample.source);
  if (it == members_.end()) {
    // Its writer's announcement has not arrived yet (different writers are not ordered):
    // park the sample until it does.
    park_locked([this, s = std::move(sample), writer]() mutable {
      admit_locked<T>(std::move(s), writer);
    });
    return;
  }
  if (it->second != writer) {
    if (replaced_.contains(writer)) return;  // a member's process before its restart
    const auto re = reannounced_.find(sample.source);
    const auto refused = refused_.find(sample.source);
    const bool was_refused = refused != refused_.end() && refused->second.contains(writer);
    if (!was_refused && re != reannounced_.end() && re->second.contains(writer)) {
      // A restarted member's sample may arrive before the rollback naming it: it waits, until
      // then or until the coordinator refuses its writer.
      park_locked([this, s = std::move(sample), writer]() mutable {
        admit_locked<T>(std::move(s), writer);
      });
      return;
    }
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
  if (session_->add(std::move(sample))) cv_.notify_all();
}

proto::MemberAnnounceMsg announcement_of(const Participant& participant, std::string member_id,
                                         proto::MemberKind kind, std::uint64_t fingerprint,
                                         std::vector<std::string> config_files,
                                         std::string build_id) {
  proto::MemberAnnounceMsg a;
  a.member_id = std::move(member_id);
  a.kind = kind;
  a.run_id = participant.options().run_id;
  a.participant_guid = participant.guid_prefix();
  a.host = host_name();
  a.pid = process_id();
  a.process_key = own_process_key();
  a.config_fingerprint = fingerprint;
  a.config_files = std::move(config_files);
  a.build_id = std::move(build_id);
  return a;
}

void MemberRuntime::announce() {
  const auto a = announcement_of(
      *participant_, agent_.member_id(), agent_.kind(), options_.config_fingerprint,
      options_.config_files,
      options_.debug_build_id.empty() ? build_identity() : options_.debug_build_id);
  announce_writer_->write(to_dds(a));
}

bool MemberRuntime::flush_writers(double timeout_s) {
  bool all = true;
  auto flush = [&](auto& w) {
    if (w && !w->wait_for_acknowledgments(timeout_s)) all = false;
  };
  std::apply([&](auto&... w) { (flush(w), ...); }, data_writers_);
  for (auto& [key, w] : patch_writers_) flush(w);
  return all;
}

void MemberRuntime::publish(const proto::FrameSamples& out) {
  proto::for_each_topic([&](auto t) {
    constexpr proto::Topic T = decltype(t)::value;
    if constexpr (proto::is_addressed(T)) {
      static_assert(T == proto::Topic::terrain_patch, "one map of writers per addressed topic");
      for (const auto& s : out.list<T>()) {
        auto& w = patch_writers_[s.vehicle_id];
        if (!w && writes_patches_) {
          w = participant_->make_writer<typename DdsType<T>::type>(
              topics::data(T), writer_profile(T), s.vehicle_id);
        }
        write_all(w, std::span(&s, 1), proto::TopicTraits<T>::name, s.vehicle_id);
      }
    } else {
      write_all(std::get<static_cast<std::size_t>(T)>(data_writers_), out.list<T>(),
                proto::TopicTraits<T>::name, agent_.vehicle_key());
    }
  });
}

void MemberRuntime::send_done(std::int64_t frame, const proto::Manifest& published,
                              double compute_s, bool finished, const std::string& error,
                              std::vector<proto::VehicleBodyMsg> body) {
  proto::FrameDoneMsg d;
  d.member_id = agent_.member_id();
  d.frame = frame;
  d.published = published;
  d.compute_s = compute_s;
  d.finished = finished;
  d.error = error;
  d.checkpoint_bytes = finished || !error.empty() ? 0 : checkpoint_bytes_;
  d.epoch = session_->epoch();
  d.body = std::move(body);
  if (options_.done_batch && !finished && error.empty()) {
    options_.done_batch->add(std::move(d));
    return;
  }
  if (!done_writer_->write(to_dds(d))) throw std::runtime_error("DDS refused a frame_done sample");
}

// A coordinator on this machine is watched through its process: its exit is seen at once, and
// a lease that expires while it still runs (a loaded machine, SIGSTOP) is not its death.
void MemberRuntime::watch_coordinator_locked() {
  const auto& c = session_->coordinator();
  if (!c || c->process_key.empty() || coordinator_watch_.watching(c->process_key)) return;
  coordinator_watch_.watch(c->process_key, [this] {
    std::lock_guard lock(mutex_);
    session_->on_coordinator_lost(now());
    cv_.notify_all();
  });
}

// A member that ends before the coordinator's readers were matched with its writers (e.g.
// one that refuses the coordinator's scenario as soon as it hears it) would go unnoticed:
// its announcement and its failure must be matched and acknowledged before it leaves.
void MemberRuntime::reach_coordinator() {
  std::string guid;
  {
    std::lock_guard lock(mutex_);
    if (session_->coordinator()) guid = session_->coordinator()->participant_guid;
  }
  GuidPrefix prefix;
  if (guid.empty() || !parse_guid_prefix(guid, prefix)) return;
  constexpr double kMatchTimeoutS = 5.0;
  if (!announce_writer_->wait_matched_by(prefix, kMatchTimeoutS) ||
      !done_writer_->wait_matched_by(prefix, kMatchTimeoutS)) {
    spdlog::warn("{}: the coordinator's readers did not match within {:g} s; it may not learn "
                 "why this member ends",
                 agent_.member_id(), kMatchTimeoutS);
  }
  announce_writer_->wait_for_acknowledgments(2.0);
}

void MemberRuntime::run_frame(const proto::FrameContext& ctx,
                              const proto::FrameSamples& inputs) {
  const auto t0 = Clock::now();
  checkpoint_bytes_ = 0;
  // Not the checkpoint this member was just restored from (resume or rollback): it exists, and
  // saving again would pass the state through the model's setters a second time.
  if (proto::checkpoint_due(ctx.frame - 1, options_.checkpoint_every) &&
      ctx.frame - 1 != restored_from_) {
    // The state after frame - 1 and the inputs of this frame: all a resumed member needs.
    checkpoint_bytes_ = record::write_member_checkpoint(
        options_.run_dir, ctx.frame - 1, options_.config_fingerprint, agent_, inputs);
  }
  proto::FrameSamples outputs;
  agent_.step(ctx, inputs, outputs);
  proto::check_outputs(outputs, ctx.frame, agent_.member_id(), agent_.vehicle_key());
  if (options_.debug_frame_delay_ms > 0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.debug_frame_delay_ms));
  }
  const double compute_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const proto::Manifest published = outputs.manifest(agent_.member_id());
  if (options_.debug_publish_delay_ms > 0) {
    send_done(ctx.frame, published, compute_s, false, "", outputs.contact_bodies);
    std::this_thread::sleep_for(std::chrono::milliseconds(options_.debug_publish_delay_ms));
    publish(outputs);
  } else {
    publish(outputs);
    send_done(ctx.frame, published, compute_s, false, "", outputs.contact_bodies);
  }
}

int MemberRuntime::end_run(const proto::MemberSession::Action& end) {
  using Outcome = proto::MemberSession::Outcome;
  end_reason_ = end.control.reason;
  if (options_.done_batch) {
    // This member answers no more grants: the process's other members no longer wait for it.
    try {
      options_.done_batch->leave(agent_.member_id());
    } catch (const std::exception& e) {
      spdlog::warn("{}: {}", agent_.member_id(), e.what());
    }
  }
  bool coordinator_lost = false;
  {
    std::lock_guard lock(mutex_);
    coordinator_lost = session_->coordinator_lost();
  }
  if (!end.error.empty() && done_writer_ && !coordinator_lost) {
    // Tell the coordinator why, so the run's one-line reason names the cause. Not a lost one:
    // after its lease expired its readers are unmatched, and waiting for them took 5 s.
    try {
      reach_coordinator();
      send_done(end.error_frame, {}, 0.0, false, end.error);
      done_writer_->wait_for_acknowledgments(1.0);
    } catch (const std::exception&) {
    }
  }
  if (end.outcome == Outcome::refused) {
    // It never took part: nothing of the agent's is finished (a refused recorder must not
    // write over the run's files), nothing is confirmed.
    spdlog::error("{}: {}", agent_.member_id(), end.control.reason);
    end_reason_ = end.control.reason;
    if (options_.on_outcome) options_.on_outcome(kExitRefused);
    return kExitRefused;
  }
  if (end.confirm && end.outcome == Outcome::failed) {
    spdlog::error("{}: {}", agent_.member_id(), end.control.reason);
  }
  int code = kExitCompleted;
  switch (end.outcome) {
    case Outcome::completed: code = kExitCompleted; break;
    case Outcome::aborted: code = kExitAborted; break;
    case Outcome::failed: code = kExitFailed; break;
    case Outcome::interrupted: code = kExitInterrupted; break;
    case Outcome::refused: code = kExitRefused; break;
  }
  std::string failed;
  try {
    agent_.finish(proto::RunEnd{end.control}, end.inputs);
  } catch (const std::exception& e) {
    // Its own failure, whatever the run's verdict: its exit status says so, and the
    // coordinator learns it with the confirmation below (a failure after the end, not a loss).
    failed = std::string("failed while finishing the run: ") + e.what();
    spdlog::error("{}: {}", agent_.member_id(), failed);
    end_reason_ = failed;
    code = kExitFailed;
  }
  if (options_.on_outcome) options_.on_outcome(code);
  if (!end.confirm) return code;
  try {
    // Whatever this member wrote must reach its readers before the process (and its shared
    // memory segments) goes away: a sample still in flight when the writer disappears is lost.
    if (!flush_writers(2.0)) {
      spdlog::warn("{}: not every reader acknowledged this member's last samples within 2 s",
                   agent_.member_id());
    }
    send_done(end.control.final_frame, {}, 0.0, true, failed);
    done_writer_->wait_for_acknowledgments(2.0);
  } catch (const std::exception& e) {
    spdlog::warn("{}: could not confirm the end of the run: {}", agent_.member_id(), e.what());
  }
  return code;
}

void MemberRuntime::prepare() {
  if (prepared_) return;
  {
    std::lock_guard lock(mutex_);
    t0_ = Clock::now();
    if (!participant_) participant_ = std::make_shared<Participant>(options_.dds);
    session_.emplace(agent_.subscriptions(), session_config(), now());
    if (options_.resume_frame >= 0) {
      restored_from_ = options_.resume_frame;
      session_->resume(record::read_member_checkpoint(options_.run_dir, options_.resume_frame,
                                                      options_.config_fingerprint, agent_));
      spdlog::info("{}: resumed from the checkpoint of frame {} in {}", agent_.member_id(),
                   options_.resume_frame, options_.run_dir);
    }
  }
  setup();
  announce();
  prepared_ = true;
  spdlog::info("{}: announced; waiting for the coordinator of run '{}' on domain {}",
               agent_.member_id(), options_.dds.run_id, options_.dds.domain_id);
}

int MemberRuntime::run(const std::atomic<bool>& interrupt) {
  using Kind = proto::MemberSession::Action::Kind;
  prepare();

  // This thread runs the frames and carries out the session's decisions; DDS callbacks only
  // feed the session and wake it.
  std::unique_lock lock(mutex_);
  bool told_admitted = !options_.late_join;
  bool told_interrupted = false;
  while (true) {
    if (interrupt.load() && !told_interrupted) {
      told_interrupted = true;
      session_->on_interrupt(now());
      if (session_->phase() == proto::MemberSession::Phase::running) {
        spdlog::warn("{}: interrupted; waiting up to {:g} s for the coordinator's verdict",
                     agent_.member_id(), options_.interrupt_grace_s);
      }
    }
    auto action = session_->poll(now());
    if (!told_admitted && session_->admitted()) {
      told_admitted = true;
      spdlog::info("{}: admitted; taking part from frame {}", agent_.member_id(),
                   session_->next_frame());
    }
    switch (action.kind) {
      case Kind::wait: {
        // Woken by every event; the interval bounds how late a signal is noticed.
        const double wait_s = std::clamp(action.wake_at_s - now(), 0.0,
                                         std::chrono::duration<double>(kPollInterval).count());
        cv_.wait_for(lock, std::chrono::duration<double>(wait_s));
        break;
      }
      case Kind::rollback: {
        // Restarted members are their new participants from now on; what their old ones
        // still deliver is of the epoch rolled back.
        for (const auto& entry : action.rejoined) {
          const auto space = entry.find(' ');
          GuidPrefix guid;
          if (space == std::string::npos || !parse_guid_prefix(entry.substr(space + 1), guid)) {
            session_->on_failure("malformed rejoined entry '" + entry + "' in a rollback grant",
                                 now());
            continue;
          }
          const std::string member = entry.substr(0, space);
          if (const auto old = members_.find(member); old != members_.end() && old->second != guid) {
            replaced_.insert(old->second);
          }
          members_[member] = guid;
        }
        std::vector<std::function<void()>> waiting;
        waiting.swap(unannounced_);
        for (auto& retry : waiting) retry();
        lock.unlock();
        spdlog::warn("{}: rolling back to the checkpoint of frame {} (a member was lost)",
                     agent_.member_id(), action.rollback_frame);
        std::string error;
        proto::FrameSamples inputs;
        try {
          inputs = record::read_member_checkpoint(options_.run_dir, action.rollback_frame,
                                                  options_.config_fingerprint, agent_);
        } catch (const std::exception& e) {
          error = e.what();
        }
        lock.lock();
        if (error.empty()) {
          restored_from_ = action.rollback_frame;
          session_->on_rolled_back(std::move(inputs), now());
          lock.unlock();
          checkpoint_bytes_ = 0;
          send_done(action.rollback_frame, {}, 0.0, false);
          lock.lock();
        } else {
          session_->on_rolled_back({}, now());
          session_->on_failure("rollback: " + error, now());
        }
        break;
      }
      case Kind::joined:
        spdlog::info("{}: joined run '{}' (coordinator on {})", agent_.member_id(),
                     options_.dds.run_id, session_->coordinator()->host);
        break;
      case Kind::step: {
        std::vector<proto::RejectedSample> rejected;
        rejected.swap(rejected_);
        lock.unlock();
        std::string error;
        try {
          if (!rejected.empty()) agent_.note_rejected(rejected);
          run_frame(action.context, action.inputs);
        } catch (const std::exception& e) {
          error = e.what();
        }
        lock.lock();
        session_->on_stepped(action.context.frame, error, now());
        break;
      }
      case Kind::finish:
        lock.unlock();
        return end_run(action);
    }
  }
}

}  // namespace syndds::dds
