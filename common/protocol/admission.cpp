#include "protocol/admission.hpp"

#include <algorithm>
#include <limits>

namespace syndds::proto {

Admission::Claim Admission::on_claim(const std::string& member, const std::string& participant,
                                     bool awaited, double now_s) {
  const auto key = std::make_pair(member, participant);
  if (std::any_of(refused_.begin(), refused_.end(), [&](const auto& r) { return r.first == key; })) {
    return Claim::refused;  // told already
  }
  const auto it = owner_.find(member);
  if (it == owner_.end()) {
    owner_[member] = participant;
    changed_ = true;
    return Claim::admitted;
  }
  if (it->second == participant) return Claim::repeated;
  if (awaited) {
    replaced_.insert(it->second);
    it->second = participant;
    std::erase_if(held_, [&](const Held& h) { return h.participant == participant; });
    changed_ = true;
    return Claim::admitted;
  }
  if (config_.restarts) {
    const bool known = std::any_of(held_.begin(), held_.end(), [&](const Held& h) {
      return h.member == member && h.participant == participant;
    });
    if (!known) held_.push_back({member, participant, now_s + config_.claim_hold_s});
    return Claim::held;
  }
  refuse_locked(member, participant, "participant " + it->second + " is " + member,
                "claimed the member");
  return Claim::refused;
}

void Admission::refuse(const std::string& member, const std::string& participant,
                       const std::string& why) {
  refuse_locked(member, participant, why, "claimed the member");
}

void Admission::refuse_locked(const std::string& member, const std::string& participant,
                              const std::string& why, const std::string& what) {
  const auto key = std::make_pair(member, participant);
  std::erase_if(held_, [&](const Held& h) { return h.member == member && h.participant == participant; });
  if (std::none_of(refused_.begin(), refused_.end(), [&](const auto& r) { return r.first == key; })) {
    refused_.emplace_back(key, why);
    changed_ = true;
  }
  Intrusion i{member, participant, what + ": " + why};
  if (std::find(intrusions_.begin(), intrusions_.end(), i) == intrusions_.end()) {
    intrusions_.push_back(std::move(i));
  }
}

bool Admission::accept(const std::string& member, const std::string& participant,
                       const std::string& what) {
  const auto it = owner_.find(member);
  if (it != owner_.end() && it->second == participant) return true;
  if (replaced_.contains(participant)) return false;  // the member's process before its restart
  const std::string why = it == owner_.end()
                              ? "no participant is " + member + " yet"
                              : "participant " + it->second + " is " + member;
  refuse_locked(member, participant, why, "wrote a " + what);
  return false;
}

void Admission::poll(double now_s) {
  std::vector<Held> due;
  for (const Held& h : held_) {
    if (now_s >= h.until_s) due.push_back(h);
  }
  for (const Held& h : due) {
    const auto it = owner_.find(h.member);
    refuse_locked(h.member, h.participant,
                  "participant " + (it == owner_.end() ? std::string("?") : it->second) + " is " +
                      h.member + " and was not lost within " +
                      std::to_string(static_cast<int>(config_.claim_hold_s)) + " s",
                  "claimed the member");
  }
}

double Admission::next_deadline_s() const {
  double t = std::numeric_limits<double>::infinity();
  for (const Held& h : held_) t = std::min(t, h.until_s);
  return t;
}

std::vector<std::string> Admission::held(const std::string& member) const {
  std::vector<std::string> out;
  for (const Held& h : held_) {
    if (h.member == member) out.push_back(h.participant);
  }
  return out;
}

void Admission::forget(const std::string& participant) {
  std::erase_if(held_, [&](const Held& h) { return h.participant == participant; });
}

std::optional<std::string> Admission::owner(const std::string& member) const {
  const auto it = owner_.find(member);
  if (it == owner_.end()) return std::nullopt;
  return it->second;
}

std::vector<std::string> Admission::admitted_list() const {
  std::vector<std::string> out;
  for (const auto& [member, participant] : owner_) out.push_back(member + " " + participant);
  return out;
}

std::vector<std::string> Admission::refused_list() const {
  std::vector<std::string> out;
  for (const auto& [key, why] : refused_) out.push_back(key.first + " " + key.second + " " + why);
  return out;
}

bool Admission::take_changed() { return std::exchange(changed_, false); }

std::vector<Intrusion> Admission::take_intrusions() { return std::exchange(intrusions_, {}); }

bool split_member_entry(const std::string& entry, std::string& member, std::string& participant,
                        std::string* rest) {
  const auto a = entry.find(' ');
  if (a == std::string::npos || a == 0) return false;
  const auto b = entry.find(' ', a + 1);
  member = entry.substr(0, a);
  participant = entry.substr(a + 1, b == std::string::npos ? std::string::npos : b - a - 1);
  if (participant.empty()) return false;
  if (rest) *rest = b == std::string::npos ? std::string() : entry.substr(b + 1);
  return true;
}

}  // namespace syndds::proto
