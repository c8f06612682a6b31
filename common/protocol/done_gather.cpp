#include "protocol/done_gather.hpp"

#include <algorithm>
#include <utility>

namespace syndds::proto {

std::vector<FrameDoneMsg> DoneGather::add(FrameDoneMsg done, double now_s) {
  std::vector<FrameDoneMsg> out;
  if (done.epoch != epoch_ || done.frame != frame_) {
    out.swap(held_);  // they answer an older grant: nothing more will join them
    epoch_ = done.epoch;
    frame_ = done.frame;
    answered_.clear();
  }
  taking_part_.insert(done.member_id);
  answered_.insert(done.member_id);
  if (held_.empty()) held_since_s_ = now_s;
  held_.push_back(std::move(done));
  auto ready = release_if_complete();
  out.insert(out.end(), std::make_move_iterator(ready.begin()),
             std::make_move_iterator(ready.end()));
  return out;
}

std::vector<FrameDoneMsg> DoneGather::leave(const std::string& member) {
  taking_part_.erase(member);
  return release_if_complete();
}

std::vector<FrameDoneMsg> DoneGather::overdue(double now_s) {
  if (held_.empty() || now_s < held_since_s_ + max_hold_s_) return {};
  return std::exchange(held_, {});
}

std::optional<double> DoneGather::deadline() const {
  if (held_.empty()) return std::nullopt;
  return held_since_s_ + max_hold_s_;
}

std::vector<FrameDoneMsg> DoneGather::release_if_complete() {
  if (held_.empty()) return {};
  const bool complete = std::includes(answered_.begin(), answered_.end(), taking_part_.begin(),
                                      taking_part_.end());
  if (!complete) return {};
  return std::exchange(held_, {});
}

}  // namespace syndds::proto
