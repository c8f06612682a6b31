#include "protocol/frame_inbox.hpp"

#include <sstream>

namespace syndds::proto {
namespace {

template <typename T>
std::uint32_t count_matching(const std::vector<T>& list, const TopicCount& entry) {
  std::uint32_t n = 0;
  for (const auto& s : list) {
    if (s.vehicle_id == entry.key && s.source == entry.writer) ++n;
  }
  return n;
}

// Moves into `out` the samples of `in` that some entry of `manifest` on `topic` announces,
// at most as many per entry as announced. Returns how many were left out.
template <typename T>
std::uint64_t take_announced(std::vector<T>& in, std::vector<T>& out, Topic topic,
                             const Manifest& manifest) {
  std::uint64_t dropped = 0;
  std::map<std::pair<std::string, std::string>, std::uint32_t> budget;
  for (const auto& e : manifest) {
    if (e.topic == topic) budget[{e.key, e.writer}] += e.count;
  }
  for (auto& s : in) {
    auto it = budget.find({s.vehicle_id, s.source});
    if (it != budget.end() && it->second > 0) {
      --it->second;
      out.push_back(std::move(s));
    } else {
      ++dropped;
    }
  }
  return dropped;
}

}  // namespace

FrameInbox::FrameInbox(std::vector<Subscription> subscriptions)
    : subscriptions_(std::move(subscriptions)) {}

bool FrameInbox::wants(Topic topic, const std::string& key) const {
  for (const auto& s : subscriptions_) {
    if (s.matches(topic, key)) return true;
  }
  return false;
}

Manifest FrameInbox::needed(const Manifest& manifest) const {
  Manifest out;
  for (const auto& e : manifest) {
    if (e.count > 0 && wants(e.topic, e.key)) out.push_back(e);
  }
  return out;
}

std::uint32_t FrameInbox::held(std::int64_t frame, const TopicCount& e) const {
  auto it = pending_.find(frame);
  if (it == pending_.end()) return 0;
  std::uint32_t n = 0;
  for_each_topic([&](auto t) {
    if (t.value == e.topic) n = count_matching(it->second.list<decltype(t)::value>(), e);
  });
  return n;
}

std::uint64_t FrameInbox::held_samples(std::int64_t frame) const {
  auto it = pending_.find(frame);
  if (it == pending_.end()) return 0;
  std::uint64_t n = 0;
  for_each_topic([&](auto t) { n += it->second.list<decltype(t)::value>().size(); });
  return n;
}

bool FrameInbox::complete(std::int64_t frame, const Manifest& manifest) const {
  // Called for every sample that arrives (MemberSession::sample_may_unblock): first the count,
  // which settles most calls without a look at each entry. A sample counts towards one entry at
  // most, so fewer samples held than announced means some entry is short.
  std::uint64_t announced = 0;
  for (const auto& e : manifest) {
    if (e.count > 0 && wants(e.topic, e.key)) announced += e.count;
  }
  if (held_samples(frame) < announced) return false;
  for (const auto& e : manifest) {
    if (e.count > 0 && wants(e.topic, e.key) && held(frame, e) < e.count) return false;
  }
  return true;
}

std::string FrameInbox::describe_missing(std::int64_t frame, const Manifest& manifest) const {
  std::ostringstream out;
  for (const auto& e : needed(manifest)) {
    const std::uint32_t have = held(frame, e);
    if (have >= e.count) continue;
    if (out.tellp() > 0) out << "; ";
    out << to_string(e.topic) << " key=" << e.key << " from " << e.writer << ": have " << have
        << " of " << e.count;
  }
  return out.str();
}

FrameSamples FrameInbox::take(std::int64_t frame, const Manifest& manifest) {
  FrameSamples out;
  auto it = pending_.find(frame);
  if (it != pending_.end()) {
    FrameSamples& in = it->second;
    for_each_topic([&](auto t) {
      constexpr Topic T = decltype(t)::value;
      unexpected_ += take_announced(in.list<T>(), out.list<T>(), T, manifest);
    });
  }
  pending_.erase(pending_.begin(), pending_.upper_bound(frame));
  last_taken_ = std::max(last_taken_, frame);
  out.sort();
  return out;
}

}  // namespace syndds::proto
