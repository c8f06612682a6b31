#pragma once
// The dones of a process's several members, sent together (proto::DoneGather decides when):
// one FrameDones sample per grant on the process's participant. The members' failures and
// replies to RunControl do not pass through here: they travel alone as FrameDone, at once.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "dds/participant.hpp"
#include "protocol/done_gather.hpp"

namespace syndds::dds {

class DoneBatch {
 public:
  /// Creates the FrameDones writer on `participant`: before the members announce themselves,
  /// so that the coordinator is matched with it by the time the first grant is answered.
  explicit DoneBatch(std::shared_ptr<Participant> participant);
  /// Sends what is still held, then stops.
  ~DoneBatch();
  DoneBatch(const DoneBatch&) = delete;
  DoneBatch& operator=(const DoneBatch&) = delete;

  /// A member's regular done (not finished, no error). Throws when DDS refuses the sample.
  void add(proto::FrameDoneMsg done);
  /// The member answers no more grants.
  void leave(const std::string& member);

  std::uint64_t samples_written() const;

 private:
  double now() const;
  void send_locked(std::vector<proto::FrameDoneMsg> dones);
  void watch();  // the thread: sends dones held past their deadline

  std::shared_ptr<Participant> participant_;
  std::unique_ptr<Writer<msg::FrameDones>> writer_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  proto::DoneGather gather_;
  std::uint64_t written_ = 0;
  bool stop_ = false;
  std::chrono::steady_clock::time_point t0_ = std::chrono::steady_clock::now();
  std::thread watcher_;
};

}  // namespace syndds::dds
