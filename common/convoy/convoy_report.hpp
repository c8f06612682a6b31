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
// - bumper gap: the smallest distance between the two vehicles' chassis boxes (placed by the
//   recorded poses, metrics/box_gap.hpp), every frame; for a follower behind its leader, the
//   bumper-to-bumper gap. With it the time the follower spent closer than its standstill gap;
// - obstacles hit (collision events) and leader-lost events of the follower;
// - stuck: whether it stopped for good while its leader drove on (kStuckWindowS below).
#include <map>
#include <string>
#include <vector>

#include "core/math.hpp"

namespace syndds::convoy {

struct TrackPoint {
  double time_s = 0.0;
  Vec2 position = Vec2::Zero();
  double speed_mps = 0.0;
  double z = 0.0;                          // height of the chassis reference point
  Quat orientation = Quat::Identity();     // of the chassis
};
using Track = std::vector<TrackPoint>;

struct Stat {
  double mean = 0.0;
  double min = 0.0;
  double max = 0.0;
  std::size_t samples = 0;
};

/// A vehicle's chassis box in its chassis reference frame (VehicleParams::chassis).
struct BodyBox {
  Vec3 centre_m = Vec3::Zero();
  Vec3 half_extents_m = Vec3::Zero();
};

/// What the bumper gap needs: both vehicles' boxes and the follower's standstill gap.
struct GapGeometry {
  BodyBox follower;
  BodyBox leader;
  double standstill_bumper_m = 0.0;
};

struct FollowerReport {
  std::string follower;
  std::string leader;          // the vehicle it follows
  Stat distance_gap_m;
  Stat time_gap_s;
  Stat cross_track_m;
  Stat bumper_gap_m;                   // box to box, every frame
  double min_bumper_gap_time_s = 0.0;  // when the smallest bumper gap happened (first time)
  double standstill_bumper_m = 0.0;    // the follower's standstill gap (bumper to bumper)
  double time_below_standstill_s = 0.0;  // frames with bumper gap < standstill, times their length
  std::size_t obstacles_hit = 0;
  std::size_t vehicle_contacts = 0;    // collision episodes with other vehicles (set by the caller)
  std::size_t leader_lost_events = 0;
  bool stuck = false;                  // stopped for good (below)
  double stuck_time_s = -1.0;          // when it was first seen stuck (end of the window)
};

/// Stuck (FollowerReport::stuck): in some window of this length the follower's progress along
/// the leader's track grew by less than kStuckProgressM while the leader drove more than
/// kStuckLeaderM.
inline constexpr double kStuckWindowS = 10.0;
inline constexpr double kStuckProgressM = 0.5;
inline constexpr double kStuckLeaderM = 5.0;

/// Distance from `p` to a polyline track; `u` gets the arc position of the closest point and
/// `inside` whether it lies strictly between the track's end points.
double distance_to_track(const std::vector<Vec2>& track, const std::vector<double>& arc,
                         const Vec2& p, double& u, bool& inside);

/// Bumper gap of one frame: the distance between the two boxes placed at the two points.
double bumper_gap(const TrackPoint& follower, const BodyBox& follower_box,
                  const TrackPoint& leader, const BodyBox& leader_box);

/// The report of one follower. Tracks are sampled at the same times (one point per frame); a
/// frame counts `heartbeat_s` towards the time below the standstill gap.
FollowerReport follower_report(const std::string& follower, const std::string& leader,
                               const Track& follower_track, const Track& leader_track,
                               std::size_t obstacles_hit, std::size_t leader_lost_events,
                               const GapGeometry& geometry = {}, double heartbeat_s = 0.01);

}  // namespace syndds::convoy
