#pragma once
// The coordinator over DDS: announces the run and the members it expects, turns DDS events
// (announcements, done reports, participants lost) into Barrier events, and publishes the
// Barrier's decisions (grants, stop, abort).
#include <atomic>
#include <condition_variable>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <variant>

#include "dds/participant.hpp"
#include "protocol/barrier.hpp"

namespace syndds::dds {

struct CoordinatorOptions {
  DdsOptions dds;
  proto::BarrierConfig barrier;
  std::uint64_t config_fingerprint = 0;
  double finish_timeout_s = 10.0;  // after stop/abort: waiting for members to confirm
  std::string scenario_name;
};

class CoordinatorService {
 public:
  explicit CoordinatorService(CoordinatorOptions options);
  ~CoordinatorService();

  /// Runs the whole run; returns 0 when it completed, 2 when aborted, 130 when interrupted.
  int run(const std::atomic<bool>& interrupt);
  const proto::RunControlMsg& result() const { return result_; }

 private:
  struct Joined { proto::MemberAnnounceMsg announce; };
  struct Done { proto::FrameDoneMsg done; };
  struct Lost { std::string guid; bool graceful; };
  using Event = std::variant<Joined, Done, Lost>;

  void setup();
  void handle(proto::Barrier& barrier, Event& event, double now);
  void wait_for_finished(proto::Barrier& barrier);

  CoordinatorOptions options_;
  std::unique_ptr<Participant> participant_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Event> events_;
  std::map<std::string, std::string> member_of_guid_;  // participant GUID prefix -> member id
  proto::RunControlMsg result_;

  std::unique_ptr<Writer<msg::MemberAnnounce>> announce_writer_;
  std::unique_ptr<Writer<msg::FrameGrant>> grant_writer_;
  std::unique_ptr<Writer<msg::RunControl>> control_writer_;
  std::unique_ptr<Reader<msg::MemberAnnounce>> announce_reader_;
  std::unique_ptr<Reader<msg::FrameDone>> done_reader_;
};

}  // namespace syndds::dds
