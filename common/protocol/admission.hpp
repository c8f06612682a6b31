#pragma once
// Who is which member: the coordinator's admission rules as a DDS-free state machine
// (docs/protocol.md, "Admission"). A member is the DDS participant the coordinator admitted
// under its id; every protocol message of that member counts only when that participant wrote
// it. Another participant that claims the id, or writes in its name, is an intruder: refused
// (it is told through the coordinator's announcement, `refused`) and recorded (`intrusions`).
// Time is passed in, so every rule is unit-testable; services/dds/coordinator_service drives it.
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace syndds::proto {

struct AdmissionConfig {
  /// on_member_loss: recover: a member's restart may announce itself before its old process's
  /// loss is seen, so a second claim is held (not refused) for `claim_hold_s`.
  bool restarts = false;
  /// Longer than the coordinator takes to see a member's process end, on this machine (0.2 s)
  /// and on another (the DDS lease, 10 s), plus the time the barrier gathers losses (1 s).
  double claim_hold_s = 12.0;
};

/// Something refused: `participant` claimed or wrote as `member`, which it is not.
struct Intrusion {
  std::string member;
  std::string participant;
  std::string what;  // "claimed the member (participant P is that member)", "wrote a frame_done"
  bool operator==(const Intrusion&) const = default;
};

class Admission {
 public:
  enum class Claim {
    admitted,  // `participant` is the member from now on
    repeated,  // it already was (a repeated announcement)
    held,      // another participant is the member; decided later (a restart, or refused)
    refused,   // not this member: told in the announcement's `refused`
  };

  explicit Admission(AdmissionConfig config = {}) : config_(config) {}

  /// An announcement for `member` that `participant` wrote (its named participant checked).
  /// `awaited`: the barrier waits for this member to announce itself again (a restart under
  /// recover): the new participant replaces the old one.
  Claim on_claim(const std::string& member, const std::string& participant, bool awaited,
                 double now_s);
  /// Refuses `participant` as `member` (a scenario mismatch, not a member, the run started):
  /// recorded as an intrusion, told in `refused`.
  void refuse(const std::string& member, const std::string& participant, const std::string& why);
  /// A protocol message of `member` written by `participant`: true when it counts. A message
  /// of the member's previous participant (replaced by a restart) is dropped quietly; any other
  /// is an intrusion, and its writer is refused as that member.
  bool accept(const std::string& member, const std::string& participant, const std::string& what);
  /// Held claims whose time ran out are refused (the claimed member's participant is alive).
  void poll(double now_s);
  /// When poll() next has something to do (infinity: nothing held).
  double next_deadline_s() const;
  /// Held claims for `member` (restarts that announced themselves early), newest last.
  std::vector<std::string> held(const std::string& member) const;
  /// Gives up a held claim (its participant left).
  void forget(const std::string& participant);

  std::optional<std::string> owner(const std::string& member) const;
  /// "MEMBER PARTICIPANT" of every admitted member, sorted by member.
  std::vector<std::string> admitted_list() const;
  /// "MEMBER PARTICIPANT why" of every refused claim, in the order refused.
  std::vector<std::string> refused_list() const;
  /// True once after admitted_list() or refused_list() changed: time to announce again.
  bool take_changed();
  /// Intrusions recorded since the last call.
  std::vector<Intrusion> take_intrusions();

 private:
  void refuse_locked(const std::string& member, const std::string& participant,
                     const std::string& why, const std::string& what);

  AdmissionConfig config_;
  std::map<std::string, std::string> owner_;  // member -> participant
  std::set<std::string> replaced_;            // participants replaced by a restart
  struct Held {
    std::string member, participant;
    double until_s = 0.0;
  };
  std::vector<Held> held_;
  std::vector<std::pair<std::pair<std::string, std::string>, std::string>> refused_;  // (m, p), why
  std::vector<Intrusion> intrusions_;
  bool changed_ = false;
};

/// Parses "MEMBER PARTICIPANT[ rest]" (entries of admitted, refused, rejoined, intrusions):
/// false when there is no participant.
bool split_member_entry(const std::string& entry, std::string& member, std::string& participant,
                        std::string* rest = nullptr);

}  // namespace syndds::proto
