#pragma once
// The coordinator over DDS: announces the run and the members it expects, turns DDS events
// (announcements, done reports, participants lost) into Barrier events, and publishes the
// Barrier's decisions (grants, stop, abort).
#include <atomic>
#include <condition_variable>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <vector>

#include "core/process_watch.hpp"
#include "dds/participant.hpp"
#include "protocol/admission.hpp"
#include "protocol/barrier.hpp"

namespace syndds::dds {

struct CoordinatorOptions {
  DdsOptions dds;
  proto::BarrierConfig barrier;
  std::uint64_t config_fingerprint = 0;
  std::vector<std::string> config_files;  // "ROLE HASH" of the fingerprinted files
  double finish_timeout_s = 10.0;  // after stop/abort: waiting for members to confirm
  std::string scenario_name;
  std::string run_dir;  // where checkpoints are declared complete (docs/checkpoints.md)
  /// Complete checkpoints kept in run_dir (checkpoint.keep_last); older ones are deleted.
  std::int64_t checkpoint_keep_last = 3;
  /// Called once the run's verdict is sent, with the exit code run() will return (unless a
  /// member fails after the end): from then on nothing can change the run's outcome, and the
  /// main program may treat a Fast DDS abort while the members leave as teardown
  /// (service::DdsTeardownGuard).
  std::function<void(int)> on_verdict;
  /// Testing (fault injection): a member's process exit is acted on this much later, as when
  /// the watch is slow to see it and a restarted member announces itself first.
  double debug_exit_notice_delay_s = 0.0;
  /// Under recover: how long a second claim of a live member is held (a restart announcing
  /// itself before its old process's loss is seen) before it is refused.
  double claim_hold_s = 12.0;
  /// The run's state for launchers (syndds_launch), replaced atomically at each change (empty:
  /// none). JSON: run_id, scenario, pid, state (joining, running, completed, aborted, interrupted),
  /// frame (the newest granted), final_frame, recoveries, reason, exit_code (once decided),
  /// failed_after_end (member -> why) and final (true in the last version this run writes).
  /// docs/deployment.md, "The launcher".
  std::string status_file;
};

class CoordinatorService {
 public:
  explicit CoordinatorService(CoordinatorOptions options);
  ~CoordinatorService();

  /// Runs the whole run; returns 0 when it completed, 2 when aborted, 130 when interrupted.
  int run(const std::atomic<bool>& interrupt);
  /// Tears the DDS entities down (also done by the destructor); idempotent.
  void close();
  const proto::RunControlMsg& result() const { return result_; }
  /// After a completed run: the members that failed after it (member -> why), as logged.
  const std::map<std::string, std::string>& failed_after_end() const { return failed_after_end_; }

 private:
  // Events are handled where they arrive (DDS receive threads) under mutex_, and a grant is
  // written from there too: no thread hop per done report. The main thread only handles
  // deadlines, signals and the end of the run.
  void setup();
  double now() const;
  /// `writer`: the GUID prefix of the participant that wrote the sample.
  void on_join(const proto::MemberAnnounceMsg& announce, const std::string& writer);
  void join_locked(const proto::MemberAnnounceMsg& announce);
  /// Announcements held back because their name belonged to a live participant: a member
  /// restarted under recover can announce itself before its old process's exit is seen here.
  /// Once the member is awaited, they are taken as its return.
  void replay_held_locked();
  void on_done(const proto::FrameDoneMsg& done, const std::string& writer);
  void count_done_sample();
  /// Writes the coordinator's announcement with the current admitted and refused lists.
  void announce_locked();
  /// The files that make a member's fingerprint differ, or the hint how to find them.
  std::string differing_files(const proto::MemberAnnounceMsg& a) const;
  /// Logs new intrusions, keeps them for the next grant, announces a changed admission.
  void note_intrusions_locked();
  void on_lost(const std::string& guid, bool graceful);
  void on_process_exit(const std::string& guid);
  void malformed(const std::string& what, const std::string& error);
  void advance_locked();
  /// Logs the lost members a recovery waits for (once per change).
  void note_recovering_locked();
  /// Logs a rollback and appends it to RUN_DIR/recoveries.csv.
  void note_recovery_locked(const proto::FrameGrantMsg& grant);
  /// Declares a checkpoint every member reported written complete (complete.yaml).
  void declare_checkpoint(const proto::CheckpointReport& report);
  void wait_for_finished(std::unique_lock<std::mutex>& lock);
  /// After a verdict given before the start: waits, at most kReachBeforeStartS, until every
  /// member the start waited for (those missing at a join timeout excepted) confirmed the
  /// verdict, or announced itself and its participant's readers matched the verdict and the
  /// announcement.
  void reach_members_before_start();
  /// Replaces options_.status_file (if any) with the run's current state; a failure to write
  /// is logged, not fatal (the run does not depend on its launcher).
  void write_status_locked(const std::string& state, int exit_code = -1, bool final = false);

  CoordinatorOptions options_;
  std::unique_ptr<Participant> participant_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::chrono::steady_clock::time_point t0_;
  std::optional<proto::Barrier> barrier_;
  proto::Admission admission_;                 // who is which member
  proto::MemberAnnounceMsg announcement_;      // this coordinator's, with admission's lists
  std::vector<std::string> intrusions_;        // for the next grant
  std::optional<proto::Barrier::Action> end_;  // stop or abort, once decided
  double next_wake_s_ = 0.0;
  std::int64_t progress_every_ = 1;
  // Participant GUID prefix -> the members it announced (several when a process hosts a group).
  std::map<std::string, std::vector<std::string>> members_of_guid_;
  // Member -> the participant that is it (the newest, after a restart under recover).
  std::map<std::string, std::string> guid_of_member_;
  std::string recovering_logged_;  // the members last logged as awaited
  // Member -> the newest announcement ignored because another participant was that member.
  std::map<std::string, proto::MemberAnnounceMsg> held_announcements_;
  // Participant GUID prefix -> its process (MemberAnnounce::process_key), when announced.
  std::map<std::string, std::string> process_of_guid_;
  // Processes of this machine whose participant's lease expired while they still ran: lost
  // only once they exit.
  ProcessWatch watch_;
  int lost_callback_ = -1;
  proto::RunControlMsg result_;
  std::map<std::string, std::string> failed_after_end_;
  std::int64_t granted_frame_ = -1;  // the newest frame granted (for the status file)
  // Member -> the participant of its newest announcement, whatever became of it.
  std::map<std::string, std::string> announced_by_;
  // Members that confirmed the verdict (a finished frame_done), admitted or not.
  std::set<std::string> verdict_heard_by_;
  std::vector<double> recovery_wall_s_;  // when each recovery was decided (Unix time, s)

  std::unique_ptr<Writer<msg::MemberAnnounce>> announce_writer_;
  std::unique_ptr<Writer<msg::FrameGrant>> grant_writer_;
  std::unique_ptr<Writer<msg::RunControl>> control_writer_;
  std::unique_ptr<Reader<msg::MemberAnnounce>> announce_reader_;
  std::unique_ptr<Reader<msg::FrameDone>> done_reader_;
  std::unique_ptr<Reader<msg::FrameDones>> dones_reader_;  // processes with several members
  std::uint64_t done_samples_ = 0;  // FrameDone and FrameDones samples received (status file)
};

}  // namespace syndds::dds
