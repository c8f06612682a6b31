#pragma once
// The coordinator's barrier as a pure state machine: events in (join, done, member lost,
// interrupt), decisions out (grant frame k with the manifest of frame k-1, stop, abort).
// Time is passed in (seconds on any monotonic clock), so every rule is unit-testable without
// DDS or threads. services/coordinator drives it from DDS callbacks.
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "protocol/messages.hpp"

namespace syndds::proto {

enum class LossPolicy : std::uint8_t { abort, continue_run, recover };

struct BarrierConfig {
  std::vector<std::string> members;  // declared by the scenario, waited for at the start
  std::vector<std::string> late_members;  // declared, may join at any time (sensor processes)
  double late_join_delay_s = 1.0;    // a late joiner is admitted this long after it announced
                                     // itself (time for every process to discover it)
  std::int64_t final_frame = 0;      // last frame to grant; frames run 0..final_frame
  double heartbeat_s = 0.01;
  double join_timeout_s = 30.0;      // from construction until every member joined
  double frame_timeout_s = 10.0;     // from a grant until every member reported it done
  LossPolicy on_member_loss = LossPolicy::abort;
  bool realtime = false;             // pace grants to the wall clock
  std::int64_t first_frame = 0;      // > 0: a run resumed from the checkpoint of first_frame - 1
  std::int64_t checkpoint_every = 0; // frames between checkpoints (0: none)
  // on_member_loss: recover (docs/checkpoints.md, "Recovering a lost member"):
  int max_recoveries = 3;            // recoveries per run; the next loss aborts it
  double rejoin_timeout_s = 60.0;    // for the lost members to announce themselves again
};

/// A recovery: members lost while frame `lost_in` ran, the run rolled back to `to_checkpoint`.
struct Recovery {
  std::int64_t lost_in = 0;
  std::int64_t to_checkpoint = 0;
  std::vector<std::pair<std::string, std::string>> members;  // member, why it was lost
};

/// A checkpoint every member reported written (FrameDone::checkpoint_bytes).
struct CheckpointReport {
  std::int64_t frame = 0;
  std::vector<std::pair<std::string, std::uint64_t>> members;  // member, bytes
  std::vector<std::string> missing;  // active members that wrote none: the checkpoint is
                                     // incomplete (a member that joined after the frame)
};

class Barrier {
 public:
  enum class Phase { joining, running, stopped, aborted };

  struct Action {
    enum class Kind { wait, grant, stop, abort };
    Kind kind = Kind::wait;
    FrameGrantMsg grant;     // Kind::grant
    RunControlMsg control;   // Kind::stop and Kind::abort
    double wake_at_s = 0.0;  // Kind::wait: call poll() again by then even without events
  };

  Barrier(BarrierConfig config, double now_s);

  /// Events. A non-empty return value is a warning: the event was ignored and why.
  std::string on_join(const std::string& member, double now_s);
  /// A member announced itself with another scenario (fingerprint) or protocol version. One
  /// the run waits for at the start aborts it (before anything ran); a late member is refused
  /// (the warning names it) and the run goes on without it.
  std::string on_config_mismatch(const std::string& member, const std::string& why, double now_s);
  std::string on_done(const FrameDoneMsg& done, double now_s);
  /// Under on_member_loss: abort (and while joining) the run aborts kLossGatherS after the
  /// first loss, naming every member lost by then (a partition or a lost host takes several
  /// at once); nothing is granted meanwhile.
  void on_member_lost(const std::string& member, const std::string& why, double now_s);
  static constexpr double kLossGatherS = 1.0;
  void on_interrupt(const std::string& why, double now_s);

  /// The next decision. Grant/stop/abort are returned once; after them poll() says wait.
  Action poll(double now_s);

  Phase phase() const { return phase_; }
  std::int64_t current_frame() const { return frame_; }
  std::vector<std::string> missing_members() const;   // not joined yet
  std::vector<std::string> pending_members() const;   // active, not done with current frame
  bool is_member(const std::string& member) const { return members_.contains(member); }
  /// After stop: true once every member still alive replied `finished`.
  bool all_finished() const;
  /// After a completed run: members that failed while finishing (their FrameDone error, or
  /// their process ended before confirming), member -> why. The run stays completed; those
  /// members report their own failure in their exit status.
  std::map<std::string, std::string> failed_after_end() const;
  RunStatsMsg stats(double now_s) const;
  /// The checkpoint reported with the frame completed last, once (nullopt: none).
  std::optional<CheckpointReport> take_checkpoint();
  /// The newest complete checkpoint (-1: none yet).
  std::int64_t last_checkpoint() const { return last_checkpoint_; }
  /// Recoveries so far (on_member_loss: recover).
  const std::vector<Recovery>& recoveries() const { return recoveries_; }
  /// The members whose loss ends the run (the abort to come or made), with why.
  const std::vector<std::pair<std::string, std::string>>& lost() const { return lost_; }
  /// Lost members the run waits for (to announce themselves again) before it rolls back.
  std::vector<std::string> rejoining_members() const;

 private:
  struct Member {
    bool late = false;       // may join after the start
    std::int64_t active_from = -1;  // first frame it takes part in (-1: not yet admitted)
    double joined_at_s = 0.0;
    bool joined = false;
    bool lost = false;       // its process died or stopped answering
    bool left = false;       // lost under the `continue` policy: no longer waited for
    bool done = false;       // done with the current frame
    bool finished = false;   // replied to stop
    bool rejoining = false;  // lost under recover: waited for to announce itself again
    Manifest published;      // in the current frame
    std::vector<VehicleBodyMsg> body;    // its collision state after the current frame
    std::uint64_t checkpoint_bytes = 0;  // in the current frame
    double response_sum_s = 0.0;
    double response_max_s = 0.0;
    double compute_sum_s = 0.0;
    std::uint64_t responses = 0;
    std::uint64_t slowest = 0;
  };

  Action abort_with(const std::string& reason, double now_s);
  Manifest collect_manifest() const;
  /// The bodies of frame_ to pass on with the next grant (select_contact_bodies).
  std::vector<VehicleBodyMsg> collect_bodies() const;
  bool everyone_done() const;
  bool active(const Member& m) const { return m.active_from >= 0 && m.active_from <= frame_; }
  /// Late joiners ready to be admitted with the grant of `frame` (they start at frame + 1).
  std::vector<std::string> admit_joiners(std::int64_t frame, double now_s);

  std::string loss_reason() const;
  /// After frame_ completed: the checkpoint its done reports carried, if one was due.
  void note_checkpoint();
  /// Under recover: waits for the lost members, then rolls every member back.
  Action poll_recovering(double now_s);

  BarrierConfig config_;
  std::map<std::string, Member> members_;
  Phase phase_ = Phase::joining;
  double created_s_ = 0.0;
  double first_grant_s_ = 0.0;
  double grant_s_ = 0.0;         // when the current frame was granted
  double end_s_ = 0.0;
  std::int64_t frame_ = -1;      // current (last granted) frame
  std::int64_t last_completed_ = -1;  // last frame every live member reported done
  Manifest last_manifest_;            // what was published in last_completed_
  std::string last_done_member_;
  std::optional<std::string> pending_abort_;
  std::vector<std::pair<std::string, std::string>> lost_;  // member, why: the abort to come
  std::optional<double> loss_abort_at_;                    // when it comes
  std::vector<std::string> departed_;  // left since the last grant, for the next one
  std::map<std::string, std::string> failed_after_end_;  // reported errors
  std::map<std::string, std::string> lost_after_end_;    // processes gone after the stop
  bool announced_end_ = false;
  std::optional<CheckpointReport> checkpoint_;  // reported, not taken yet
  std::int64_t last_checkpoint_ = -1;           // newest complete checkpoint
  std::int64_t restored_checkpoint_ = -1;       // the one the run resumed or rolled back to
  std::uint32_t epoch_ = 0;
  std::optional<Recovery> recovering_;          // lost members being waited for
  bool rolling_back_ = false;                   // the current frame is the rollback's
  std::optional<double> rejoin_deadline_;
  std::vector<Recovery> recoveries_;
};

}  // namespace syndds::proto
