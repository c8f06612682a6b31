#pragma once
// Runs one Agent as a barrier member over DDS: announce, wait for the coordinator, then for
// every grant k: wait until every announced sample stamped k-1 that the agent subscribes to has
// arrived (the data barrier), step, publish, report done with the manifest of what was written.
// The rules (which frame runs when, with which inputs, how the run ends) are decided by
// proto::MemberSession; this class is the plumbing: DDS entities, who may write what, threads.
#include <atomic>
#include <condition_variable>
#include <chrono>
#include <functional>
#include <map>
#include <set>
#include <memory>
#include <mutex>
#include <optional>
#include <tuple>
#include <utility>

#include "dds/convert.hpp"
#include "core/process_watch.hpp"
#include "dds/participant.hpp"
#include "protocol/agent.hpp"
#include "protocol/member_session.hpp"

namespace syndds::dds {

class DoneBatch;
class GrantHub;

struct MemberRuntimeOptions {
  DdsOptions dds;
  std::uint64_t config_fingerprint = 0;
  std::vector<std::string> config_files;  // "ROLE HASH" of the fingerprinted files
  double heartbeat_s = 0.01;      // frame length, from the scenario
  double join_timeout_s = 30.0;   // waiting for the coordinator's announcement
  double input_timeout_s = 10.0;  // waiting for announced samples once a frame is granted
  double final_timeout_s = 5.0;   // gathering the final frame's samples after the run ended
  double interrupt_grace_s = 2.0; // after a signal: waiting for the coordinator's verdict
  bool late_join = false;         // may join a run under way: starts after the grant naming it
  // Checkpoints (docs/checkpoints.md): written to / read from run_dir.
  std::string run_dir;
  std::int64_t checkpoint_every = 0;  // frames between checkpoints (0: none)
  std::int64_t resume_frame = -1;     // >= 0: start from the checkpoint of this frame
  bool rejoin = false;  // restarted after it was lost (recover): waits for the rollback
  /// Called once the agent finished the run, with the exit code run() will return, before the
  /// last DDS exchanges (flushing, confirming): nothing after it changes this member's outcome
  /// (see service::DdsTeardownGuard).
  std::function<void(int)> on_outcome;
  /// A process hosting several members: their regular dones go out together through it (one
  /// sample per grant, created on the members' shared participant); null: each done alone.
  std::shared_ptr<DoneBatch> done_batch;
  /// The same process's grant reader, shared: each grant is decoded once for all its members
  /// (created before any of them announces itself); null: the member reads grants itself.
  std::shared_ptr<GrantHub> grant_hub;

  // Test knobs (never set by the launcher):
  int debug_frame_delay_ms = 0;    // sleep this long in every frame: a slow process
  int debug_publish_delay_ms = 0;  // send done first, data this long after: data that arrives
                                   // after the grant it belongs to
  bool debug_skip_data_barrier = false;  // start frames without waiting for announced data
  std::string debug_build_id;            // announced instead of build_identity() (another build)
};

/// A process's announcement of `member_id` on `participant`: who and where it is (host, pid,
/// process key), the run, the scenario's fingerprint and files, and its build.
proto::MemberAnnounceMsg announcement_of(const Participant& participant, std::string member_id,
                                         proto::MemberKind kind, std::uint64_t fingerprint,
                                         std::vector<std::string> config_files,
                                         std::string build_id);

/// Process exit codes shared by every service (documented in docs/protocol.md).
enum ExitCode : int {
  kExitCompleted = 0,
  kExitConfigError = 1,
  kExitAborted = 2,       // the coordinator aborted the run (reason in its log and summary)
  kExitFailed = 3,        // this process failed: coordinator lost, protocol violation, DDS error
  kExitRefused = 4,       // the coordinator refused this process as the member it claimed to be
                          // (another participant is that member: docs/protocol.md, "Admission")
  kExitInterrupted = 130,
};

class MemberRuntime {
 public:
  /// With `shared` the member uses that participant (several members hosted by one process,
  /// syndds_group: one participant, one discovery, samples between them stay in the process);
  /// without, it creates its own from options.dds.
  MemberRuntime(proto::Agent& agent, MemberRuntimeOptions options,
                std::shared_ptr<Participant> shared = nullptr);
  ~MemberRuntime();

  /// Creates the DDS entities and announces the member (run() does it when not done before).
  /// A process hosting many members prepares them one after another: creating every member's
  /// readers and writers at once from many threads starved the participant's own
  /// announcements at startup (32 members in one process).
  void prepare();
  /// Runs until the run ends; returns an ExitCode. `interrupt` is polled (signals).
  int run(const std::atomic<bool>& interrupt);
  /// Tears the DDS entities down (also done by the destructor); idempotent.
  void close();

  /// Why the run ended (for logs): the coordinator's reason or this member's own.
  const std::string& end_reason() const { return end_reason_; }

 private:
  void setup();
  void announce();
  double now() const;
  proto::MemberSessionConfig session_config() const;
  /// Records who announced itself as which member (with mutex_ held).
  void note_announcement(const proto::MemberAnnounceMsg& a, const GuidPrefix& writer);
  /// Stores a data sample in the inbox if its writer is the participant that announced itself
  /// as the sample's source; otherwise records the rejection (with mutex_ held).
  template <proto::Topic T>
  void admit_locked(typename proto::TopicTraits<T>::Msg sample, const GuidPrefix& writer);
  void run_frame(const proto::FrameContext& ctx, const proto::FrameSamples& inputs);
  void publish(const proto::FrameSamples& out);
  bool flush_writers(double timeout_s);  // true when every reader acknowledged everything
  void send_done(std::int64_t frame, const proto::Manifest& published, double compute_s,
                 bool finished, const std::string& error = "",
                 std::vector<proto::VehicleBodyMsg> body = {});
  /// Before reporting a failure: waits (bounded) until the coordinator's readers are matched
  /// with this member's announcement and done writers and the announcement is acknowledged.
  void reach_coordinator();
  void watch_coordinator_locked();
  /// Applies the coordinator's admitted and refused lists to who may write as whom.
  void apply_admission_locked(const proto::MemberAnnounceMsg& coordinator);
  /// Parks a sample until its writer is decided on (bounded: the oldest go first).
  void park_locked(std::function<void()> retry);
  /// Carries out the session's finish decision; returns the exit code.
  int end_run(const proto::MemberSession::Action& end);

  proto::Agent& agent_;
  MemberRuntimeOptions options_;
  std::shared_ptr<Participant> participant_;
  int lost_callback_ = -1;
  // The coordinator's process, when it runs on this machine: lost when it exits, not when its
  // lease expires while it still runs.
  ProcessWatch coordinator_watch_;

  // DDS callbacks only store what arrives in the session and wake the thread in run(), which
  // runs the frames: a long frame must not block a DDS thread (it would hold Fast DDS's
  // internal locks, delay acknowledgements, even liveliness).
  std::mutex mutex_;
  std::condition_variable cv_;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
  std::optional<proto::MemberSession> session_;  // from run() on
  std::map<std::string, GuidPrefix> members_;  // member id -> participant that announced it
  std::vector<std::function<void()>> unannounced_;  // samples waiting for their writer's
                                                    // announcement
  std::vector<proto::RejectedSample> rejected_;     // not yet told to the agent
  // Participants that announced a member already announced by another (restarts or
  // impostors), and participants a rollback replaced by the member's restarted process.
  std::map<std::string, std::set<GuidPrefix>> reannounced_;
  std::set<GuidPrefix> replaced_;
  // Participants the coordinator refused as a member (MemberAnnounce::refused), per member.
  std::map<std::string, std::set<GuidPrefix>> refused_;

  // One writer and one reader slot per data topic (null when the agent does not use it).
  template <proto::Topic T>
  using DataWriterPtr = std::unique_ptr<Writer<typename DdsType<T>::type>>;
  template <proto::Topic T>
  using DataReaderPtr = std::unique_ptr<Reader<typename DdsType<T>::type>>;
  template <template <proto::Topic> class Ptr, typename Seq>
  struct PerTopic;
  template <template <proto::Topic> class Ptr, std::size_t... I>
  struct PerTopic<Ptr, std::index_sequence<I...>> {
    using type = std::tuple<Ptr<proto::kAllDataTopics[I]>...>;
  };
  using AllTopics = std::make_index_sequence<std::size(proto::kAllDataTopics)>;

  std::unique_ptr<Writer<msg::MemberAnnounce>> announce_writer_;
  std::unique_ptr<Writer<msg::FrameDone>> done_writer_;
  typename PerTopic<DataWriterPtr, AllTopics>::type data_writers_;
  // Addressed topics (proto::is_addressed): a writer per destination vehicle, made when first
  // written to, in that vehicle's partition only.
  std::map<std::string, DataWriterPtr<proto::Topic::terrain_patch>> patch_writers_;
  bool writes_patches_ = false;  // the agent declared terrain_patch
  std::unique_ptr<Reader<msg::MemberAnnounce>> announce_reader_;
  std::unique_ptr<Reader<msg::FrameGrant>> grant_reader_;
  int grant_hub_id_ = -1;  // with options_.grant_hub: this member's handlers there
  std::unique_ptr<Reader<msg::RunControl>> control_reader_;
  typename PerTopic<DataReaderPtr, AllTopics>::type data_readers_;

  std::string end_reason_;
  bool prepared_ = false;
  std::uint64_t checkpoint_bytes_ = 0;  // written before the current frame, for its done
  std::int64_t restored_from_ = -1;     // the checkpoint last restored (resume or rollback)
};

}  // namespace syndds::dds
