#pragma once
// When the dones of a process that hosts several members (syndds_group) are sent: together, one
// FrameDones sample per grant instead of one FrameDone per member, so that what the coordinator
// receives per frame grows with the processes, not with the members (docs/protocol.md, "Dones
// of a process with several members"). The rule, without DDS or threads:
//
// - A member takes part from its first regular done until it leaves (its run ended).
// - A regular done (of a frame, not finished, no error) is held until every member taking part
//   has answered the same grant (epoch, frame); then the held ones go out together.
// - A done of another grant sends the held ones first: they answer an older grant.
// - A member that leaves no longer holds the others back.
// - Dones held for max_hold_s go out as they are (a member that stopped answering without
//   leaving must not hide the others' dones from the coordinator's deadline and its message).
//
// Nothing waits on another member that the coordinator does not also wait on: a member taking
// part answers every grant of the barrier, so holding a done until the process's last one is
// ready costs the coordinator no time.
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "protocol/messages.hpp"

namespace syndds::proto {

class DoneGather {
 public:
  explicit DoneGather(double max_hold_s = 0.5) : max_hold_s_(max_hold_s) {}

  /// Adds a member's regular done. Returns the dones to send now, oldest first (empty: the
  /// process's other members have not answered this grant yet).
  std::vector<FrameDoneMsg> add(FrameDoneMsg done, double now_s);
  /// `member` answers no more grants (its run ended, or it failed or finished): returns what
  /// no longer waits for it.
  std::vector<FrameDoneMsg> leave(const std::string& member);
  /// The held dones, if held since max_hold_s before now_s or longer.
  std::vector<FrameDoneMsg> overdue(double now_s);
  /// When overdue() will have something to send (nullopt: nothing is held).
  std::optional<double> deadline() const;

  std::size_t held() const { return held_.size(); }

 private:
  /// The held dones if every member taking part answered the current grant.
  std::vector<FrameDoneMsg> release_if_complete();

  double max_hold_s_;
  std::set<std::string> taking_part_;
  std::uint32_t epoch_ = 0;       // the grant answered by the held dones ...
  std::int64_t frame_ = -1;
  std::set<std::string> answered_;  // ... and who answered it (held or already sent)
  std::vector<FrameDoneMsg> held_;
  double held_since_s_ = 0.0;
};

}  // namespace syndds::proto
