#pragma once
// Episodes of the convoy-follow task (docs/learning.md, "Convoy-follow environment"): a leader
// path in a 90 x 90 m area, the follower's and the leader's start on it, eight obstacles beside
// it, and the scenario (YAML for the normal loader) that runs them. Pure functions of the seed:
// no simulation here, so the tests can check every variant cheaply.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/math.hpp"

namespace syndds::learn {

/// The heartbeat (frame period) of the environment's scenarios.
inline constexpr double kConvoyEnvHeartbeatS = 0.01;

inline constexpr double kConvoyAreaM = 90.0;     // the area is [0, 90] x [0, 90] m
inline constexpr int kConvoyPathVariants = 16;   // 2 shapes x mirror E-W x mirror N-S x rotate

enum class ConvoyTerrain { rigid, scm_hard, scm_soft };
enum class ConvoyDynamics { reduced, full };

/// Path variant v (0..15): bit 0 C shape (else S), bit 1 mirrored east-west, bit 2 mirrored
/// north-south, bit 3 rotated 90 degrees anticlockwise about the area's centre.
struct PathVariant {
  bool c_shape = false;
  bool mirror_east_west = false;
  bool mirror_north_south = false;
  bool rotated = false;
  static PathVariant from_index(int v);
};

/// The leader path of a variant: points about 1 m apart, first to last in driving order
/// (x east, y north, metres). S: from one corner region to the opposite one with two bends of
/// opposite sense; C: out along one side, a half circle of 30 m, back along the same side.
std::vector<Vec2> convoy_path(int variant);

struct ConvoyObstacle {
  std::string id;     // rock1, tree2, bush3, ...
  std::string label;  // rock | tree | bush
  Vec2 centre = Vec2::Zero();
  double radius_m = 0.0;
  double height_m = 0.0;
};

/// Which episodes reset() draws: the paper's S / C paths in the 90 m area, random obstacle
/// courses (the statistical study's generator, common/course, on training seeds of their own),
/// or both (even episode seeds paper, odd ones courses).
enum class ConvoyEpisodeKind { paper, courses, mixed };
ConvoyEpisodeKind parse_episode_kind(const std::string& name);

/// Course seeds of training episodes: kTrainingCourseSeed + (episode seed mod
/// kTrainingCourses), far from the study's seeds (1, 2, ...), which stay unseen. (A seed
/// whose fields give no path stands for seed + kTrainingCourses, and so on.)
inline constexpr std::uint64_t kTrainingCourseSeed = 1000000;
inline constexpr std::uint64_t kTrainingCourses = 512;

struct ConvoyEpisodeOptions {
  ConvoyEpisodeKind kind = ConvoyEpisodeKind::paper;
  double gap_m = 15.0;            // the leader starts this far ahead along the path
  int obstacles = 8;
  double obstacle_offset_min_m = 4.0;  // obstacle centre to path, drawn in [min, max]
  double obstacle_offset_max_m = 10.0;
  double clearance_m = 2.2;       // obstacle edge to path at least this (the vehicle's width)
  /// Above 0: the leader drives its path displaced sideways by a sine (a leader that wanders
  /// as a follower does), amplitude drawn in [0, leader_wobble_m], wavelength in [8, 30] m,
  /// the amplitude cut so that the sine's curvature stays under leader_wobble_curvature_per_m,
  /// faded in over the leader's first 10 m. `path` (the reward's reference) stays the
  /// planned one. Drawn from a stream of its own: the episode's other draws do not change.
  double leader_wobble_m = 0.0;
  double leader_wobble_curvature_per_m = 0.05;
  /// The fraction of episodes in which the vehicle followed is itself a classical follower
  /// (controller `follower`, the convoy scenarios' gap) of a head vehicle that drives the path
  /// from gap_m further on: the trail the policy follows is then a follower's, as behind the
  /// first follower of a convoy (its leader_path, wobbled or not, is then unused). Drawn from
  /// a stream of its own; episodes too short for a third vehicle stay unchained.
  double chain_fraction = 0.0;
};

struct ConvoyEpisode {
  int variant = 0;                 // paper episodes: the path variant; course episodes: -1
  std::uint64_t course_seed = 0;   // course episodes: the course's seed
  Vec2 world_min = Vec2(-10.0, -10.0);  // the scenario's world box
  Vec2 world_max = Vec2(100.0, 100.0);
  std::vector<Vec2> path;          // the whole path of the variant
  double path_length_m = 0.0;
  double follower_arc_m = 0.0;     // where the follower starts (arc length along the path)
  double leader_arc_m = 0.0;
  Vec2 follower_start = Vec2::Zero();
  double follower_yaw_rad = 0.0;   // anticlockwise from east (the path's direction there)
  Vec2 leader_start = Vec2::Zero();
  double leader_yaw_rad = 0.0;
  std::vector<Vec2> leader_path;   // the leader's path from its start to the end (wobbled
                                   // if leader_wobble_m > 0)
  double leader_wobble_m = 0.0;    // the drawn amplitude (0: none)
  /// Chained episodes (ConvoyEpisodeOptions::chain_fraction): the head's start, gap_m ahead of
  /// the leader, and its path from there; the leader then follows the head.
  bool chained = false;
  double head_arc_m = 0.0;
  Vec2 head_start = Vec2::Zero();
  double head_yaw_rad = 0.0;
  std::vector<Vec2> head_path;
  std::vector<ConvoyObstacle> obstacles;
};

/// The episode of `seed`: variant, follower start drawn in the first half of the path, the
/// leader gap_m ahead of it, obstacles beside the path ahead of the follower. Deterministic.
ConvoyEpisode make_convoy_episode(std::uint64_t seed, const ConvoyEpisodeOptions& options = {});

/// Distance from `p` to the polyline `path`.
double distance_to_path(const std::vector<Vec2>& path, const Vec2& p);

struct ConvoyScenarioOptions {
  ConvoyTerrain terrain = ConvoyTerrain::rigid;
  ConvoyDynamics dynamics = ConvoyDynamics::reduced;  // the follower's; the leader is reduced
  bool camera = false;            // the follower's rig: convoy_camera (else convoy)
  double target_speed_mps = 5.0;  // the leader's ramp cap
  double accel_mps2 = 0.47;       // the leader's ramp (the paper's)
  double end_time_s = 70.0;
  double scm_spacing_m = 0.2;     // coarse soil grid over the area only
  std::uint64_t seed = 1;         // the scenario seed (sensor noise, ...)
  /// Rigid terrain: the ground's colour in the camera (scenario terrain.colour); unset: grey.
  std::optional<std::array<double, 3>> ground_colour;
  /// Rigid terrain: the ground's Coulomb friction coefficient (scenario terrain.friction).
  double friction = 0.8;
};

inline constexpr const char* kConvoyLeaderId = "leader";
inline constexpr const char* kConvoyFollowerId = "follower";
inline constexpr const char* kConvoyHeadId = "head";  // chained episodes: the leader's leader

/// The scenario of an episode as YAML for scenario::parse_scenario: the leader (reduced
/// dynamics, path follower on the speed ramp, V2V at 10 Hz; in a chained episode a classical
/// follower of the head, which is the path follower), the follower (controller external: the
/// environment's agent drives it), the obstacles, the terrain; no recorder.
std::string convoy_scenario_yaml(const ConvoyEpisode& episode, const ConvoyScenarioOptions& o);

}  // namespace syndds::learn
