#pragma once
// The convoy report of a run (convoy.json, and a table in summary.txt): for each follower,
// measured against the vehicle it follows, from the recorded ground truth.
//
// - distance gap: centre-to-centre distance to the vehicle followed, every frame;
// - time gap: how long ago the vehicle followed passed the point of its recorded track closest
//   to the follower, every frame in which the follower moves (> 0.5 m/s) and is on that track;
// - cross-track: distance from the follower to the recorded track of the vehicle followed, over
//   the common stretch only: from where the follower passes the start of that track to where
//   the track ends (points whose closest track point is an end point are not counted);
// - obstacles hit (collision events) and leader-lost events of the follower.
#include <map>
#include <string>
#include <vector>

#include "core/math.hpp"

namespace syndds::convoy {

struct TrackPoint {
  double time_s = 0.0;
  Vec2 position = Vec2::Zero();
  double speed_mps = 0.0;
};
using Track = std::vector<TrackPoint>;

struct Stat {
  double mean = 0.0;
  double min = 0.0;
  double max = 0.0;
  std::size_t samples = 0;
};

struct FollowerReport {
  std::string follower;
  std::string leader;          // the vehicle it follows
  Stat distance_gap_m;
  Stat time_gap_s;
  Stat cross_track_m;
  std::size_t obstacles_hit = 0;
  std::size_t leader_lost_events = 0;
};

/// Distance from `p` to a polyline track; `u` gets the arc position of the closest point and
/// `inside` whether it lies strictly between the track's end points.
double distance_to_track(const std::vector<Vec2>& track, const std::vector<double>& arc,
                         const Vec2& p, double& u, bool& inside);

/// The report of one follower. Tracks are sampled at the same times (one point per frame).
FollowerReport follower_report(const std::string& follower, const std::string& leader,
                               const Track& follower_track, const Track& leader_track,
                               std::size_t obstacles_hit, std::size_t leader_lost_events);

}  // namespace syndds::convoy
