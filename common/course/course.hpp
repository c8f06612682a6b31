#pragma once
// The paper's random obstacle courses (docs/ensemble.md): a 100 x 100 m field, x east 0..100,
// y north 0..100, start at the south-west corner (0, 0), goal at the north-east corner
// (100, 100); four fixed obstacles on the diagonal and 30 random ones. A path from start to goal
// keeping the vehicle's width of clearance from every obstacle is planned by particle swarm
// optimisation and checked exactly; a visibility (tangent) graph gives the reference shortest
// path the tests compare it with.
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/math.hpp"

namespace syndds::course {

struct Circle {
  Vec2 centre = Vec2::Zero();
  double radius = 0.0;
};

struct FieldParams {
  double size_m = 100.0;         // square field [0, size]^2
  int random_count = 30;
  double radius_min_m = 5.0;
  double radius_max_m = 7.0;
  // Two circles may overlap by at most this fraction of the smaller radius:
  // centre distance >= r1 + r2 - overlap_fraction * min(r1, r2).
  double overlap_fraction = 0.5;
  int fixed_count = 4;           // on the diagonal at fractions 1/5, 2/5, 3/5, 4/5
  double fixed_radius_m = 8.0;
  // Random obstacles keep their edge this far from the start and the goal.
  double keep_out_m = 10.0;
  int attempts_per_obstacle = 10000;  // rejection sampling bound, then the field is redrawn
};

struct Field {
  FieldParams params;
  Vec2 start = Vec2::Zero();
  Vec2 goal = Vec2::Zero();
  std::vector<Circle> obstacles;  // the fixed ones first, then the random ones
};

/// Error of course generation (no field, no path): the caller draws another field.
struct CourseError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Sequential uniform stream: std::mt19937_64 (its output is fixed by the C++ standard) seeded
/// through SplitMix64 with (seed, stream), and our own transform to [0, 1) so nothing depends on
/// the standard library's distributions (as common/sensors/random.hpp).
class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t stream);
  double uniform() { return static_cast<double>(engine_() >> 11) * (1.0 / 9007199254740992.0); }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }

 private:
  std::mt19937_64 engine_;
};

/// The field of `seed`, draw `draw` (a caller redraws with draw + 1 when no path is found).
/// Throws CourseError when rejection sampling does not place every obstacle.
Field generate_field(std::uint64_t seed, int draw = 0, const FieldParams& params = {});

/// The rules generate_field guarantees, as a list of violations (empty: the field is valid).
std::vector<std::string> field_violations(const Field& field);

// ---- paths ----

/// Distance from point p to segment ab.
double segment_point_distance(const Vec2& a, const Vec2& b, const Vec2& p);
double polyline_length(const std::vector<Vec2>& points);
/// Smallest (distance to circle centre - radius) over all segments and circles: the clearance
/// of the polyline from the obstacles' edges (negative inside one).
double polyline_clearance(const std::vector<Vec2>& points, const std::vector<Circle>& circles);
/// Whether every point lies in [0, size]^2 (then so does the polyline: the square is convex).
bool polyline_in_square(const std::vector<Vec2>& points, double size_m, double tol = 1e-9);

/// Exact shortest path from start to goal in [0, size]^2 avoiding the open discs: Dijkstra on
/// the tangent graph (bitangent segments between circles, tangents from start and goal, arcs
/// along the circles). Returns its length, and the path sampled (arcs every <= 0.5 m) in
/// `points` if given; +infinity when start and goal are not connected.
double reference_shortest_path(const Vec2& start, const Vec2& goal,
                               const std::vector<Circle>& circles, double size_m,
                               std::vector<Vec2>* points = nullptr);

struct PlannerParams {
  double clearance_m = 2.0;     // the vehicle's width (paper): kept from every obstacle edge
  double margin_m = 0.5;        // planned with clearance + margin, checked with clearance
  int waypoints = 14;           // K intermediate waypoints per particle
  int particles = 40;
  int iterations = 200;
  int swarms = 3;               // independent swarms per attempt, the best feasible one wins
  int attempts = 2;             // each retry doubles particles and iterations, new streams
  double inertia = 0.7298;      // constriction-factor PSO (Clerc & Kennedy 2002)
  double cognitive = 1.49618;
  double social = 1.49618;
  double penalty_per_m = 1000.0;  // cost per metre of penetration into the clearance
  double margin_penalty_per_m = 20.0;  // and into the margin
  int smoothing_passes = 3;     // Chaikin corner cutting, fewer if clearance would be lost
};

struct PlannedPath {
  std::vector<Vec2> waypoints;  // smoothed polyline start..goal, clearance checked
  std::vector<Vec2> raw;        // the PSO polyline (start, K waypoints, goal)
  double length_m = 0.0;        // of `waypoints`
  double clearance_m = 0.0;     // exact polyline_clearance of `waypoints`
  int attempt = 0;              // which attempt succeeded
  int smoothing_passes = 0;     // how many passes were kept
};

/// PSO shortest path through the field keeping params.clearance_m from every obstacle, in the
/// square. Deterministic per seed. Throws CourseError when no attempt yields a feasible path.
PlannedPath plan_path(const Field& field, std::uint64_t seed, const PlannerParams& params = {});

// ---- scenario ----

enum class Terrain { rigid, scm_hard, scm_soft };
Terrain parse_terrain(const std::string& name);  // throws std::invalid_argument naming it
std::string terrain_name(Terrain terrain);

/// How a course is made from its seed (docs/ensemble.md, "Protocols"):
///  - current: the field is redrawn until a path keeps 2 m from the full-size circles; the
///    leader's speed ramp is capped (CourseOptions::target_speed_mps);
///  - paper: the first field of the seed is always used; the path only has to avoid the
///    circles, and every obstacle is then shrunk until it leaves 2 m to the path (the paper
///    scales its obstacle meshes so); the ramp is not capped before the path's end.
enum class Protocol { current, paper };
Protocol parse_protocol(const std::string& name);  // throws std::invalid_argument naming it
std::string protocol_name(Protocol protocol);

struct CourseOptions {
  std::uint64_t seed = 0;
  Terrain terrain = Terrain::rigid;
  std::string convoy = "1L3F";  // 1L3F, 2L2F or 3L1F
  // Cap of the leader's 0.47 m/s2 ramp (current protocol; the paper protocol's ramp is capped
  // only by the speed it could reach at the path's end, and this is ignored).
  double target_speed_mps = 5.0;
  // The followers' controller: empty for the classical follower, else a learned policy file
  // (`controller: {type: policy, model: ...}`, docs/learning.md).
  std::string follower_policy;
  /// The followers' sensor rig (config/sensors/<rig>.yaml): `convoy` (GPS, compass,
  /// tachometer), or `convoy_camera` for a policy that also looks through the front camera.
  /// The last vehicle's rig, when it films the chase video, is <rig>_chase (convoy_chase for
  /// convoy): the same sensors first, the chase camera after them.
  std::string follower_rig = "convoy";
  /// The followers steer along the trail of the convoy's head (`trail: head`) instead of the
  /// vehicle ahead's (docs/convoy.md, "Whose trail").
  bool follower_trail_head = false;
  /// The last vehicle carries a third-person chase camera and writes a video (rig
  /// convoy_chase). Rendering and encoding it takes most of a run's time (4-6x the rest,
  /// docs/performance.md): a study leaves it out; it changes nothing the metrics measure.
  bool chase_video = true;
};

struct Course {
  Protocol protocol = Protocol::current;
  Field field;
  PlannedPath path;
  int draw = 0;  // how many fields were redrawn before a path was found
  /// The obstacles as the scenario places them, one per field obstacle in the same order: the
  /// field's circles (current protocol), or each shrunk to leave 2 m to the planned path
  /// (paper protocol; radius 0: shrunk to nothing, left out).
  std::vector<Circle> placed;
  /// Paper protocol: the factor every circle was shrunk by for planning, 1 when the field as
  /// drawn has a way through; less when its circles close every way (docs/ensemble.md).
  double planning_scale = 1.0;
};

/// The field and path of `seed` under the current protocol: redraws the field (up to
/// `max_draws`) while no path keeps 2 m from the circles. Throws CourseError otherwise.
Course make_course(std::uint64_t seed, int max_draws = 20);

/// The paper protocol's course of `seed`: field draw 0, a path avoiding the circles (planned
/// with them shrunk by the largest factor of 1, 0.9, ..., 0.1 that opens a way), then every
/// obstacle shrunk to leave kPaperClearanceM to the path (the polyline and the spline the
/// leader drives). Never redraws. Throws CourseError only if even 0.1 leaves no way.
Course make_paper_course(std::uint64_t seed);
Course make_course(std::uint64_t seed, Protocol protocol);
/// How many placed obstacles are smaller than drawn (first) and left out (second).
std::pair<int, int> count_scaled(const Course& course);

constexpr double kPaperClearanceM = 2.0;   // the vehicle's width (paper)
constexpr double kPaperMinRadiusM = 0.25;  // a shrunk obstacle smaller than this is left out

/// The paper's obstacle scaling: each circle keeps its radius or shrinks to leave
/// kPaperClearanceM to both the polyline `waypoints` and the spline the leader drives through
/// them, whichever is nearer; one smaller than kPaperMinRadiusM gets radius 0 (left out).
std::vector<Circle> shrink_to_clearance(const std::vector<Circle>& circles,
                                        const std::vector<Vec2>& waypoints);

/// The complete scenario YAML of a course (docs/ensemble.md). Throws std::invalid_argument
/// for an unknown convoy mix.
std::string scenario_yaml(const Course& course, const CourseOptions& options);

}  // namespace syndds::course
