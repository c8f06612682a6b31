#pragma once
// The grants of a process that hosts several members (syndds_group), read and decoded once on
// the process's participant and handed to each member: one reader of the coordinator's grants
// per process instead of one per member. Each member receives the grant without its manifest,
// and the manifest once by reference, from which it keeps its own entries
// (proto::MemberSession::on_grant).
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "dds/participant.hpp"
#include "protocol/messages.hpp"

namespace syndds::dds {

class GrantHub {
 public:
  using Sink = std::function<void(proto::FrameGrantMsg grant, const proto::Manifest& manifest)>;
  using Failure = std::function<void(const std::string& why)>;

  /// Creates the reader on `participant`. Grants that arrive before a member is added are not
  /// handed to it: add every member before any of them announces itself (the coordinator
  /// grants nothing before every member announced).
  explicit GrantHub(std::shared_ptr<Participant> participant);
  ~GrantHub();
  GrantHub(const GrantHub&) = delete;
  GrantHub& operator=(const GrantHub&) = delete;

  /// A member's handlers: every grant, or why a grant was malformed. Returns its id.
  int add(Sink on_grant, Failure on_malformed);
  /// After it returns, the member's handlers are not called any more.
  void remove(int id);

 private:
  std::shared_ptr<Participant> participant_;
  std::mutex mutex_;
  std::map<int, std::pair<Sink, Failure>> members_;
  int next_id_ = 0;
  std::unique_ptr<Reader<msg::FrameGrant>> reader_;
};

}  // namespace syndds::dds
