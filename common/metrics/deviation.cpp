#include "metrics/deviation.hpp"

#include <algorithm>
#include <limits>
#include <set>
#include <stdexcept>

namespace syndds::metrics {
namespace {

// Arc lengths are sums over thousands of frames: a sample this close past the end is the end.
constexpr double kRoundingM = 1e-9;

class Accumulator {
 public:
  void add(double v) {
    sum_ += v;
    max_ = std::max(max_, v);
    ++n_;
  }
  Deviation result() const {
    if (n_ == 0) return {};
    return {sum_ / static_cast<double>(n_), max_, n_};
  }

 private:
  double sum_ = 0.0;
  double max_ = 0.0;
  std::size_t n_ = 0;
};

// Index of the point of `t` closest to `p`; the first of equals, so that a vehicle standing
// still is clipped where it arrived.
std::size_t closest_index(const Trajectory& t, const Vec2& p) {
  std::size_t best = 0;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double d2 = (t[i].position - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = i;
    }
  }
  return best;
}

// A point of a trajectory between two frames: where, and how fast.
struct Located {
  Vec2 position;
  double speed_mps;
};

Located between(const TrajectoryPoint& a, const TrajectoryPoint& b, double w) {
  return {a.position + w * (b.position - a.position),
          a.speed_mps + w * (b.speed_mps - a.speed_mps)};
}

// The point of the polyline t[first..] closest to `p` (the first of equals).
Located closest_on(const Trajectory& t, std::size_t first, const Vec2& p) {
  Located best{t[first].position, t[first].speed_mps};
  double best_d2 = (best.position - p).squaredNorm();
  for (std::size_t i = first; i + 1 < t.size(); ++i) {
    const Vec2 ab = t[i + 1].position - t[i].position;
    const double len2 = ab.squaredNorm();
    const double w = len2 > 0.0 ? std::clamp((p - t[i].position).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const Located c = between(t[i], t[i + 1], w);
    const double d2 = (c.position - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best = c;
    }
  }
  return best;
}

double arc_length(const Trajectory& t, std::size_t first, std::size_t last) {
  double s = 0.0;
  for (std::size_t i = first; i < last; ++i) s += (t[i + 1].position - t[i].position).norm();
  return s;
}

}  // namespace

Deviations deviations(const Trajectory& follower, const Trajectory& leader,
                      const Settings& settings) {
  if (!(settings.spacing_m > 0.0)) {
    throw std::invalid_argument("metrics: spacing_m must be > 0");
  }
  Deviations d;
  if (follower.empty() || leader.empty()) return d;
  d.follower_start_index = closest_index(follower, leader.front().position);
  d.leader_end_index = closest_index(leader, follower.back().position);
  d.leader_segment_m = arc_length(leader, 0, d.leader_end_index);
  d.follower_segment_m = arc_length(follower, d.follower_start_index, follower.size() - 1);
  if (d.leader_end_index == 0) return d;

  Accumulator path, abs_speed, rel_speed;
  // Walk the leader's clipped segment once; sample k lies at arc length k * spacing, counted
  // as an integer so that no sample is lost or doubled to rounding.
  double arc = 0.0;  // arc length at leader[i]
  std::size_t k = 0;
  for (std::size_t i = 0; i < d.leader_end_index; ++i) {
    const double len = (leader[i + 1].position - leader[i].position).norm();
    if (len <= 0.0) continue;  // standing still: no arc length, no sample
    // A sample on a frame belongs to the next segment; the last segment takes its end too,
    // and a sample a rounding error past it (arc lengths are sums of many steps). Same sum as
    // leader_segment_m, so `last` is exact.
    const bool last = arc + len >= d.leader_segment_m;
    for (;; ++k) {
      const double s = static_cast<double>(k) * settings.spacing_m;
      if (last ? s > arc + len + kRoundingM : s >= arc + len) break;
      const Located l = between(leader[i], leader[i + 1], std::min(1.0, (s - arc) / len));
      const Located f = closest_on(follower, d.follower_start_index, l.position);
      const double gap = (f.position - l.position).norm();
      path.add(gap);
      d.series.push_back({s, gap, l.speed_mps, f.speed_mps});
      if (s >= settings.speed_skip_m) {
        const double dv = std::abs(f.speed_mps - l.speed_mps);
        abs_speed.add(dv);
        if (l.speed_mps >= settings.min_leader_speed_mps) rel_speed.add(dv / l.speed_mps);
      }
    }
    arc += len;
  }
  d.path_m = path.result();
  d.abs_speed_mps = abs_speed.result();
  d.rel_speed = rel_speed.result();
  d.samples = d.path_m.samples;
  return d;
}

SpeedSummary speed_summary(const Trajectory& t, const Settings& settings) {
  SpeedSummary out;
  if (t.empty()) return out;
  out.distance_m = arc_length(t, 0, t.size() - 1);
  std::optional<std::size_t> first, last;
  for (std::size_t i = 0; i < t.size(); ++i) {
    out.max_mps = std::max(out.max_mps, t[i].speed_mps);
    if (t[i].speed_mps >= settings.min_leader_speed_mps) {
      if (!first) first = i;
      last = i;
    }
  }
  if (first && *last > *first) {
    out.mean_moving_mps =
        arc_length(t, *first, *last) / (t[*last].time_s - t[*first].time_s);
  }
  return out;
}

std::map<std::string, ChainLink> resolve_chains(
    const std::map<std::string, std::string>& follows) {
  std::map<std::string, ChainLink> out;
  for (const auto& [follower, followed] : follows) {
    ChainLink link{followed, followed, 1};
    std::set<std::string> seen = {follower};
    std::string chain = follower;
    for (auto next = follows.find(link.leader); next != follows.end();
         next = follows.find(link.leader)) {
      chain += " -> " + link.leader;
      if (!seen.insert(link.leader).second) {
        throw std::invalid_argument("follow chain without a leader: " + chain);
      }
      link.leader = next->second;
      ++link.position;
    }
    out[follower] = link;
  }
  return out;
}

}  // namespace syndds::metrics
