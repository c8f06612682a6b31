#include "dds/coordinator_service.hpp"

#include <spdlog/spdlog.h>

#include <chrono>

#include "dds/convert.hpp"
#include "dds/member_runtime.hpp"

namespace syndds::dds {
namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

CoordinatorService::CoordinatorService(CoordinatorOptions options) : options_(std::move(options)) {}

CoordinatorService::~CoordinatorService() {
  announce_reader_.reset();
  done_reader_.reset();
}

void CoordinatorService::setup() {
  participant_ = std::make_unique<Participant>(options_.dds);
  participant_->set_lost_callback([this](const std::string& guid, bool graceful) {
    std::lock_guard lock(mutex_);
    events_.push_back(Lost{guid, graceful});
    cv_.notify_all();
  });
  announce_reader_ = participant_->make_reader<msg::MemberAnnounce>(
      topics::kMemberAnnounce, profiles::kProtocolReader, [this](msg::MemberAnnounce&& m) {
        if (m.kind() == msg::MEMBER_COORDINATOR) return;
        try {
          auto a = from_dds(m);
          std::lock_guard lock(mutex_);
          events_.push_back(Joined{std::move(a)});
          cv_.notify_all();
        } catch (const std::exception& e) {
          spdlog::error("coordinator: dropped malformed member_announce: {}", e.what());
        }
      });
  done_reader_ = participant_->make_reader<msg::FrameDone>(
      topics::kFrameDone, profiles::kProtocolReader, [this](msg::FrameDone&& m) {
        try {
          auto d = from_dds(m);
          std::lock_guard lock(mutex_);
          events_.push_back(Done{std::move(d)});
          cv_.notify_all();
        } catch (const std::exception& e) {
          spdlog::error("coordinator: dropped malformed frame_done from {}: {}", m.member_id(),
                        e.what());
        }
      });
  grant_writer_ =
      participant_->make_writer<msg::FrameGrant>(topics::kFrameGrant, profiles::kProtocolWriter);
  control_writer_ =
      participant_->make_writer<msg::RunControl>(topics::kRunControl, profiles::kProtocolWriter);
  announce_writer_ = participant_->make_writer<msg::MemberAnnounce>(topics::kMemberAnnounce,
                                                                    profiles::kProtocolWriter);
  proto::MemberAnnounceMsg a;
  a.member_id = "coordinator";
  a.kind = proto::MemberKind::coordinator;
  a.run_id = options_.dds.run_id;
  a.participant_guid = participant_->guid_prefix();
  a.host = host_name();
  a.pid = process_id();
  a.config_fingerprint = options_.config_fingerprint;
  a.expected_members = options_.barrier.members;
  announce_writer_->write(to_dds(a));
}

void CoordinatorService::handle(proto::Barrier& barrier, Event& event, double now) {
  if (auto* j = std::get_if<Joined>(&event)) {
    const auto& a = j->announce;
    if (!barrier.is_member(a.member_id)) {
      spdlog::warn("coordinator: ignoring {} (pid {} on {}): not a member of this scenario",
                   a.member_id, a.pid, a.host);
      return;
    }
    if (a.config_fingerprint != options_.config_fingerprint) {
      barrier.on_interrupt("member " + a.member_id + " on " + a.host +
                               " loaded a different scenario or overrides (fingerprint " +
                               std::to_string(a.config_fingerprint) + ", coordinator " +
                               std::to_string(options_.config_fingerprint) + ")",
                           now);
      return;
    }
    if (a.protocol_version != proto::kProtocolVersion) {
      barrier.on_interrupt("member " + a.member_id + " speaks protocol version " +
                               std::to_string(a.protocol_version),
                           now);
      return;
    }
    member_of_guid_[a.participant_guid] = a.member_id;
    const std::string warning = barrier.on_join(a.member_id, now);
    if (!warning.empty()) {
      spdlog::warn("coordinator: {}", warning);
    } else {
      spdlog::debug("coordinator: {} joined (pid {} on {})", a.member_id, a.pid, a.host);
    }
  } else if (auto* d = std::get_if<Done>(&event)) {
    const std::string warning = barrier.on_done(d->done, now);
    if (!warning.empty()) spdlog::warn("coordinator: {}", warning);
  } else if (auto* l = std::get_if<Lost>(&event)) {
    auto it = member_of_guid_.find(l->guid);
    if (it == member_of_guid_.end()) return;
    barrier.on_member_lost(it->second,
                           l->graceful ? "its DDS participant left (process ended)"
                                       : "liveliness lost (no DDS announcement within the lease)",
                           now);
  }
}

void CoordinatorService::wait_for_finished(proto::Barrier& barrier) {
  const auto t0 = Clock::now();
  std::unique_lock lock(mutex_);
  while (!barrier.all_finished() && seconds_since(t0) < options_.finish_timeout_s) {
    cv_.wait_for(lock, std::chrono::milliseconds(50));
    while (!events_.empty()) {
      Event e = std::move(events_.front());
      events_.pop_front();
      lock.unlock();
      handle(barrier, e, seconds_since(t0));
      lock.lock();
    }
  }
  if (!barrier.all_finished()) {
    spdlog::warn("coordinator: not every member confirmed the end of the run within {} s",
                 options_.finish_timeout_s);
  }
}

int CoordinatorService::run(const std::atomic<bool>& interrupt) {
  setup();
  const auto t0 = Clock::now();
  auto now = [&] { return seconds_since(t0); };
  proto::Barrier barrier(options_.barrier, now());
  spdlog::info("coordinator: run '{}' on domain {}, waiting for {} members", options_.dds.run_id,
               options_.dds.domain_id, options_.barrier.members.size());

  bool interrupted = false;
  const std::int64_t progress_every = std::max<std::int64_t>(1, options_.barrier.final_frame / 10);
  while (true) {
    std::deque<Event> batch;
    {
      std::lock_guard lock(mutex_);
      batch.swap(events_);
    }
    for (auto& e : batch) handle(barrier, e, now());
    if (interrupt.load() && !interrupted) {
      interrupted = true;
      barrier.on_interrupt("interrupted (signal to the coordinator)", now());
    }
    auto action = barrier.poll(now());
    using Kind = proto::Barrier::Action::Kind;
    if (action.kind == Kind::grant) {
      if (action.grant.frame == 0) {
        spdlog::info("coordinator: all members joined after {:.2f} s; starting", now());
      } else if (action.grant.frame % progress_every == 0) {
        spdlog::info("coordinator: frame {}/{}", action.grant.frame, options_.barrier.final_frame);
      }
      if (!grant_writer_->write(to_dds(action.grant))) {
        barrier.on_interrupt("DDS refused a frame_grant sample", now());
      }
      continue;
    }
    if (action.kind == Kind::stop || action.kind == Kind::abort) {
      result_ = action.control;
      control_writer_->write(to_dds(action.control));
      if (action.kind == Kind::stop) {
        const auto& s = action.control.stats;
        spdlog::info("coordinator: run completed: {} frames, {:.2f} s simulated in {:.2f} s "
                     "(real-time factor {:.3f})",
                     s.frames, s.sim_time_s, s.wall_time_s, s.real_time_factor);
      } else {
        spdlog::error("coordinator: run aborted: {}", action.control.reason);
      }
      wait_for_finished(barrier);
      control_writer_->wait_for_acknowledgments(1.0);
      if (action.kind == Kind::stop) return kExitCompleted;
      return interrupted ? kExitInterrupted : kExitAborted;
    }
    // Wait for the next event, the barrier's next deadline, or a signal.
    std::unique_lock lock(mutex_);
    const double wake = std::min(action.wake_at_s, now() + 0.05);
    cv_.wait_for(lock, std::chrono::duration<double>(std::max(0.0, wake - now())),
                 [&] { return !events_.empty(); });
  }
}

}  // namespace syndds::dds
