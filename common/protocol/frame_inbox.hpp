#pragma once
// The data barrier on the receiving side. DDS does not order samples across topics or writers,
// so the arrival of grant k does not prove the arrival of the data stamped k-1. The grant
// carries a manifest (who wrote how many samples on which topic and key in frame k-1); the
// inbox says the frame is complete only when it holds every sample of the manifest that it
// subscribes to, and hands out exactly those samples, in canonical order.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "protocol/agent.hpp"

namespace syndds::proto {

class FrameInbox {
 public:
  explicit FrameInbox(std::vector<Subscription> subscriptions);

  const std::vector<Subscription>& subscriptions() const { return subscriptions_; }
  bool wants(Topic topic, const std::string& key) const;

  /// Stores a sample of topic T if it is subscribed and not older than the frames still to be
  /// taken. Returns false when the sample was not kept.
  template <Topic T>
  bool add(typename TopicTraits<T>::Msg sample) {
    if (!wants(T, sample.vehicle_id)) return false;
    if (sample.frame <= last_taken_) return false;  // late duplicate of a frame already consumed
    pending_[sample.frame].template list<T>().push_back(std::move(sample));
    return true;
  }
  template <typename Msg>
  bool add(Msg sample) {
    return add<TopicOf<Msg>::value>(std::move(sample));
  }

  /// The entries of `manifest` this inbox depends on.
  Manifest needed(const Manifest& manifest) const;
  /// True when every needed entry of `manifest` is held for `frame`.
  bool complete(std::int64_t frame, const Manifest& manifest) const;
  /// Human-readable list of what is still missing, e.g.
  /// "vehicle_state key=v2 from vehicle/v2: have 0 of 1".
  std::string describe_missing(std::int64_t frame, const Manifest& manifest) const;

  /// Removes and returns the samples of `frame` covered by `manifest` (sorted), and forgets
  /// everything stamped at or before `frame`. Samples the manifest does not announce are
  /// dropped and counted in unexpected_samples().
  FrameSamples take(std::int64_t frame, const Manifest& manifest);

  /// After a rollback to the checkpoint of `frame`: accepts samples stamped after `frame`
  /// again. Those held already stay: whether they came before the rollback or after (a member
  /// that rolled back sooner), a run is deterministic, so a frame's samples are the same in
  /// every epoch, and take() hands out as many as announced.
  void reset(std::int64_t frame) {
    pending_.erase(pending_.begin(), pending_.upper_bound(frame));
    last_taken_ = frame;
  }

  std::uint64_t unexpected_samples() const { return unexpected_; }
  std::int64_t last_taken_frame() const { return last_taken_; }

 private:
  std::uint32_t held(std::int64_t frame, const TopicCount& entry) const;
  std::uint64_t held_samples(std::int64_t frame) const;

  std::vector<Subscription> subscriptions_;
  std::map<std::int64_t, FrameSamples> pending_;
  std::int64_t last_taken_ = -1;
  std::uint64_t unexpected_ = 0;
};

}  // namespace syndds::proto
