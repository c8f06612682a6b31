#include "convoy/convoy_report.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "metrics/box_gap.hpp"

namespace syndds::convoy {
namespace {

class Accumulator {
 public:
  void add(double v) {
    sum_ += v;
    min_ = std::min(min_, v);
    max_ = std::max(max_, v);
    ++n_;
  }
  Stat stat() const {
    if (n_ == 0) return {};
    return {sum_ / static_cast<double>(n_), min_, max_, n_};
  }

 private:
  double sum_ = 0.0;
  double min_ = std::numeric_limits<double>::infinity();
  double max_ = -std::numeric_limits<double>::infinity();
  std::size_t n_ = 0;
};

}  // namespace

double bumper_gap(const TrackPoint& follower, const BodyBox& follower_box,
                  const TrackPoint& leader, const BodyBox& leader_box) {
  const auto box = [](const TrackPoint& p, const BodyBox& b) {
    const Pose pose{Vec3(p.position.x(), p.position.y(), p.z), p.orientation};
    return metrics::place_box(pose, b.centre_m, b.half_extents_m);
  };
  return metrics::box_distance(box(follower, follower_box), box(leader, leader_box));
}

double distance_to_track(const std::vector<Vec2>& track, const std::vector<double>& arc,
                         const Vec2& p, double& u, bool& inside) {
  double best = std::numeric_limits<double>::infinity();
  u = 0.0;
  for (std::size_t i = 0; i + 1 < track.size(); ++i) {
    const Vec2 ab = track[i + 1] - track[i];
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - track[i]).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const double d = (track[i] + t * ab - p).norm();
    if (d < best) {
      best = d;
      u = arc[i] + t * (arc[i + 1] - arc[i]);
    }
  }
  if (track.size() == 1) {
    best = (track[0] - p).norm();
    u = 0.0;
  }
  const double end = arc.empty() ? 0.0 : arc.back();
  inside = u > 1e-9 && u < end - 1e-9;
  return best;
}

FollowerReport follower_report(const std::string& follower, const std::string& leader,
                               const Track& follower_track, const Track& leader_track,
                               std::size_t obstacles_hit, std::size_t leader_lost_events,
                               const GapGeometry& geometry, double heartbeat_s) {
  FollowerReport r;
  r.standstill_bumper_m = geometry.standstill_bumper_m;
  r.follower = follower;
  r.leader = leader;
  r.obstacles_hit = obstacles_hit;
  r.leader_lost_events = leader_lost_events;

  // The leader's track as a polyline with distinct points (a standing vehicle adds nothing),
  // and the time it passed each point (the first time).
  std::vector<Vec2> track;
  std::vector<double> arc, passed_s;
  for (const auto& p : leader_track) {
    if (!track.empty() && (p.position - track.back()).norm() < 0.05) continue;
    arc.push_back(track.empty() ? 0.0 : arc.back() + (p.position - track.back()).norm());
    track.push_back(p.position);
    passed_s.push_back(p.time_s);
  }

  Accumulator distance, time_gap, cross, bumper;
  std::size_t below = 0;
  double min_gap = std::numeric_limits<double>::infinity();
  const std::size_t n = std::min(follower_track.size(), leader_track.size());
  for (std::size_t k = 0; k < n; ++k) {
    const auto& f = follower_track[k];
    distance.add((f.position - leader_track[k].position).norm());
    const double gap = bumper_gap(f, geometry.follower, leader_track[k], geometry.leader);
    if (gap < min_gap) {
      min_gap = gap;
      r.min_bumper_gap_time_s = f.time_s;
    }
    bumper.add(gap);
    if (gap < geometry.standstill_bumper_m) ++below;
    if (track.size() < 2) continue;
    double u = 0.0;
    bool inside = false;
    const double d = distance_to_track(track, arc, f.position, u, inside);
    if (!inside) continue;
    cross.add(d);
    if (f.speed_mps > 0.5) {
      const auto it = std::upper_bound(arc.begin(), arc.end(), u);
      const std::size_t i = static_cast<std::size_t>(it - arc.begin()) - 1;
      const double len = arc[i + 1] - arc[i];
      const double w = len > 0.0 ? (u - arc[i]) / len : 0.0;
      const double t_leader = passed_s[i] + w * (passed_s[i + 1] - passed_s[i]);
      time_gap.add(f.time_s - t_leader);
    }
  }
  // Stuck: over some window of kStuckWindowS the follower's progress along the leader's track
  // (its closest point's arc position; before the track's start, minus its distance to the
  // start; off the track's ends, held) grew by less than kStuckProgressM while the leader drove
  // more than kStuckLeaderM: the leader drives on and the follower does not come along.
  if (track.size() >= 2 && n > 0) {
    const std::size_t window =
        static_cast<std::size_t>(std::llround(kStuckWindowS / std::max(heartbeat_s, 1e-6)));
    std::vector<double> progress(n), driven(n);
    double held = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      double u = 0.0;
      bool inside = false;
      const double d = distance_to_track(track, arc, follower_track[k].position, u, inside);
      if (inside) {
        held = u;
      } else if (u <= 0.0) {
        held = -d;
      }
      progress[k] = held;
      driven[k] = k == 0 ? 0.0
                         : driven[k - 1] + (leader_track[k].position - leader_track[k - 1].position).norm();
    }
    for (std::size_t k = window; k < n; ++k) {
      if (progress[k] - progress[k - window] < kStuckProgressM &&
          driven[k] - driven[k - window] > kStuckLeaderM) {
        r.stuck = true;
        r.stuck_time_s = follower_track[k].time_s;
        break;
      }
    }
  }
  r.distance_gap_m = distance.stat();
  r.time_gap_s = time_gap.stat();
  r.cross_track_m = cross.stat();
  r.bumper_gap_m = bumper.stat();
  r.time_below_standstill_s = static_cast<double>(below) * heartbeat_s;
  return r;
}

}  // namespace syndds::convoy
