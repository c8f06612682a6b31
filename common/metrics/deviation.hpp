#pragma once
// The deviation metrics of the paper ("Enabling Artificial Intelligence Studies in Off-Road
// Mobility Through Physics-Based Simulation of Multiagent Scenarios", ASME JCISE 2022; see
// docs/sources.md): how far a follower strays from the path and speed of the leader at the head
// of its convoy. Definitions and the choices the paper leaves open: docs/convoy.md.
//
//  1. Common segment. Start clip: the follower's point closest to the leader's start; end clip:
//     the leader's point closest to the follower's end. Only the clipped trajectories are used.
//  2. The leader's clipped segment is sampled at equal arc-length spacing; each sample is paired
//     with the closest point of the follower's clipped trajectory (a polyline: the projection,
//     with the speed interpolated there).
//  3. m_p: distance between paired points; m_as = |v_follower - v_leader|; m_rs = m_as /
//     v_leader. The speed metrics ignore the first `speed_skip_m` of the leader's segment (the
//     start from rest), and m_rs ignores samples where the leader is slower than
//     `min_leader_speed_mps` (a ratio to a near-zero speed says nothing).
//
// Pure functions of the tracks: the recorder writes them to metrics.json at the end of a run.
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/math.hpp"

namespace syndds::metrics {

struct TrajectoryPoint {
  double time_s = 0.0;
  Vec2 position = Vec2::Zero();
  double speed_mps = 0.0;
};
/// One point per recorded frame, in time order.
using Trajectory = std::vector<TrajectoryPoint>;

struct Settings {
  double spacing_m = 0.5;             // arc length between samples of the leader's segment
  double speed_skip_m = 10.0;         // the paper: speed metrics ignore the first 10 m
  double min_leader_speed_mps = 0.5;  // m_rs: samples with a slower leader are skipped
};

/// Mean and maximum over the samples that count (both 0 when `samples` is 0).
struct Deviation {
  double avg = 0.0;
  double max = 0.0;
  std::size_t samples = 0;
};

/// One sample of the leader's clipped segment and the follower's point paired with it: the
/// curves behind the averages (deviation and speeds along the leader's path).
struct Sample {
  double arc_m = 0.0;               // arc length along the leader's segment
  double path_m = 0.0;              // distance to the paired follower point
  double leader_speed_mps = 0.0;
  double follower_speed_mps = 0.0;  // interpolated at the paired point
};

/// The metrics of one follower against one leader, with the clip and sample details.
struct Deviations {
  Deviation path_m;         // m_p
  Deviation abs_speed_mps;  // m_as
  Deviation rel_speed;      // m_rs (a fraction of the leader's speed)
  std::size_t samples = 0;  // samples of the leader's segment (= path_m.samples)
  // Start clip: index (into the follower's trajectory) of its point closest to the leader's
  // start; end clip: index (into the leader's) of its point closest to the follower's end.
  std::size_t follower_start_index = 0;
  std::size_t leader_end_index = 0;
  double leader_segment_m = 0.0;    // arc length of the leader's clipped trajectory
  double follower_segment_m = 0.0;  // arc length of the follower's clipped trajectory
  std::vector<Sample> series;       // every sample, in arc-length order (size `samples`)
};

/// The six-metrics computation minus obstacles (those are events, not geometry). Empty
/// trajectories, or a leader segment of zero length, give zero samples.
Deviations deviations(const Trajectory& follower, const Trajectory& leader,
                      const Settings& settings = {});

/// How fast a vehicle drove: the paper's observation that leaders on soft soil cannot reach
/// their target speed is about these numbers.
struct SpeedSummary {
  double max_mps = 0.0;
  // Distance over the time from the first to the last frame at which the vehicle moved at
  // `min_leader_speed_mps` or more (the start from rest and the stop at the end stay in; the
  // standing before and after do not). 0 when it never moved that fast.
  double mean_moving_mps = 0.0;
  double distance_m = 0.0;  // arc length of the whole trajectory
};
SpeedSummary speed_summary(const Trajectory& t, const Settings& settings = {});

/// A follower's place in its convoy.
struct ChainLink {
  std::string leader;   // the vehicle at the head of the follow chain (it follows nobody)
  std::string follows;  // the vehicle directly followed
  int position = 0;     // 1: right behind the leader
};

/// Resolves follow chains: `follows` maps each follower to the vehicle it follows (f2 -> f1,
/// f1 -> l1 gives f2 the leader l1 at position 2). Throws std::invalid_argument naming the
/// vehicles of a cycle.
std::map<std::string, ChainLink> resolve_chains(const std::map<std::string, std::string>& follows);

}  // namespace syndds::metrics
