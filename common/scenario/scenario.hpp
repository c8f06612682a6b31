#pragma once
// Scenario files (config/scenarios/*.yaml): strict schema, documented in docs/scenario.md.
// Loading validates everything a process needs before any DDS traffic: time contract,
// world, vehicles and their definition files, sensor rigs, controllers, member list, budgets.
// Plain structs only: nothing here builds a terrain, a renderer or a vehicle model, so the
// coordinator and syndds_plan load a scenario in constant memory per sensor and soil patch.
// The processes that simulate build those from these structs (make_terrain and
// load_scenario below, in the library syndds_scenario).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "control/path_follower.hpp"
#include "convoy/follower.hpp"
#include "convoy/v2v_config.hpp"
#include "core/config_files.hpp"
#include "protocol/barrier.hpp"
#include "scm/scm_params.hpp"
#include "sensors/rig_config.hpp"
#include "terrain/heightmap_spec.hpp"
#include "terrain/terrain.hpp"
#include "vehicle/vehicle_params.hpp"
#include "world/obstacle.hpp"

namespace syndds::scenario {

// Budgets (docs/scenario.md, "Budgets"): what one run may ask for, refused at load.
/// Simulated seconds (time.end_time_s, --duration): 11.6 days, 1e8 frames at 10 ms.
inline constexpr double kMaxEndTimeS = 1e6;
/// Dynamics steps per frame (heartbeat_s / step_s).
inline constexpr std::int64_t kMaxStepsPerFrame = 10000;
/// Vehicles of one run, and its barrier members (processes besides the coordinator): every
/// member joins one coordinator within coordinator.join_timeout_s, and Fast DDS gives a host
/// about 120 participants per domain (unicast ports 7410 + 250 d + 2 p stay inside the
/// domain's 250 ports): 48 vehicles with their controllers and the recorder are 97 members.
inline constexpr std::size_t kMaxVehicles = 48;
inline constexpr std::size_t kMaxMembers = 100;
/// World box (`world:`): positions beyond float precision of the renderers (1e5 m: 8 mm) or a
/// side longer than 2 km (a flat ground is rendered over it at 2 m) are refused.
inline constexpr double kMaxWorldCoordinateM = 1e5;
inline constexpr double kMaxWorldSideM = 2000.0;
/// Vertices of the SCM soil patch (each process holding the soil keeps the whole grid).
inline constexpr double kMaxScmVertices = 8.0 * 1024 * 1024;
/// Pixels of a height-map image (decoded whole, 24 bytes a vertex): a 2 km map at 1 m.
inline constexpr double kMaxHeightmapPixels = 2049.0 * 2049.0;
/// coordinator.join_timeout_s and frame_timeout_s: one day.
inline constexpr double kMaxTimeoutS = 86400.0;

/// The area every start, waypoint and obstacle lies in (`world:`; default +-1 km).
struct WorldConfig {
  double x_min_m = -1000.0;
  double x_max_m = 1000.0;
  double y_min_m = -1000.0;
  double y_max_m = 1000.0;
  bool contains(double x, double y) const {
    return x >= x_min_m && x <= x_max_m && y >= y_min_m && y <= y_max_m;
  }
};

struct TimeConfig {
  double step_s = 0.002;        // dynamics step
  double heartbeat_s = 0.01;    // frame length; an integer multiple of step_s
  double end_time_s = 10.0;
  bool realtime = false;
  std::int64_t steps_per_frame() const;
  std::int64_t final_frame() const;  // frames run 0..final_frame; t_final = final_frame * hb
};

struct CoordinatorConfig {
  double join_timeout_s = 30.0;
  double frame_timeout_s = 10.0;
  proto::LossPolicy on_member_loss = proto::LossPolicy::abort;
  int max_recoveries = 3;          // on_member_loss: recover
  double rejoin_timeout_s = 60.0;  // on_member_loss: recover
};

struct DdsConfig {
  int domain_id = 0;
  // default (shared memory + UDP) | udp | udp_redundant (UDP, every datagram sent to two
  // ports of its receiver: for lossy networks, docs/deployment.md "Running on several hosts")
  std::string transport = "default";
  std::string discovery_server;       // "ADDR:PORT"; empty: multicast discovery
  // DDS Security (security: {enabled: true, dir: ...}): the folder make_security.sh wrote,
  // relative to the scenario file; empty: off.
  std::string security_dir;
};

struct TerrainConfig {
  std::string type = "rigid";  // rigid (flat plane) | heightmap | scm (deformable soil)
  double friction = 0.8;
  double height_m = 0.0;       // rigid: plane height
  terrain::HeightmapSpec heightmap;  // type heightmap (the image is decoded by make_terrain)
  scm::ScmParams scm;                // type scm
  /// rigid and heightmap: the ground's colour in the cameras (linear RGB in [0, 1]) instead of
  /// the type's grey; nothing else (physics, the lidar's reflectance) changes.
  std::optional<std::array<double, 3>> colour;
  bool deformable() const { return type == "scm"; }
};

struct ControllerConfig {
  std::string type = "path_follower";  // path_follower | follower | policy | external | none
  std::vector<Vec2> waypoints;         // path_follower
  bool closed = false;
  control::PathFollowerConfig follower;
  /// path_follower: from this simulated time on, full brake and no throttle (an emergency
  /// stop; the path still steers). Unset: never.
  std::optional<double> stop_at_s;
  convoy::FollowerConfig convoy;       // follower and policy: the vehicle followed (convoy.leader)
  /// follower and policy: `trail: head`, steer along the trail of the convoy's head (the end
  /// of the follow chain; convoy.trail_of once the scenario is read) instead of the leader's.
  bool trail_of_head = false;
  std::string policy_file;             // policy: the learned policy (syndds_train's policy.pt)
  /// policy: a new action every period; 0 (the default): the policy's own, the control period
  /// it was trained with (its metadata's frames_per_step).
  double policy_period_s = 0.0;
  /// Runs as the member controller/<id> (path_follower, follower and policy).
  bool is_builtin() const { return type == "path_follower" || follows(); }
  /// Follows another vehicle of the scenario (convoy.leader) from its V2V messages.
  bool follows() const { return type == "follower" || type == "policy"; }
};

/// The sensors a vehicle carries (`sensors:` of a vehicle entry).
struct VehicleSensorsConfig {
  sensors::SensorRig rig;
  bool save_images = false;  // camera frames as PNG (and frame metadata) in the run directory
  bool video = false;        // camera frames as an MJPG video in the run directory
  bool late_join = false;    // the sensor process may join a run already under way
};

struct VehicleConfig {
  std::string id;
  std::string model;                   // as written in the scenario
  std::string dynamics = "reduced";    // reduced (kinematic bicycle) | full (ODE multibody)
  vehicle::VehicleParams params;
  Pose start;
  ControllerConfig controller;
  std::optional<VehicleSensorsConfig> sensors;
  std::optional<convoy::V2VConfig> v2v;  // broadcasts V2V messages (needs GPS, compass, tachometer)
  /// GPS, IMU, compass or tachometer: simulated in the vehicle process at the dynamics rate.
  bool has_interoceptive_sensors() const;
  /// Cameras, lidars or radars: rendered by the vehicle's own sensor process ("sensor/<id>").
  bool has_rendered_sensors() const { return sensors && sensors->rig.has_rendered_sensors(); }
};

/// `checkpoint:` (docs/checkpoints.md): every member writes its state every `every_s` of
/// simulated time; 0 = never. Once a checkpoint is complete, the run directory keeps the
/// `keep_last` newest complete checkpoints up to it and deletes the older ones (complete or not).
struct CheckpointConfig {
  static constexpr std::int64_t kDefaultKeepLast = 3;
  double every_s = 0.0;
  std::int64_t every_frames = 0;  // every_s / heartbeat_s
  std::int64_t keep_last = kDefaultKeepLast;  // >= 1
  bool enabled() const { return every_frames > 0; }
};

struct RecorderConfig {
  bool enabled = true;
  /// Files the recorder does not write (`recorder.skip`, by name without ".csv"; one of
  /// kSkippableFiles). A file whose samples come on a topic of their own (commands.csv from
  /// driver_command, gps.csv from gps_fix, ...) is then not subscribed to at all, which is
  /// where the time goes (docs/performance.md). vehicles.csv and events.csv, which the
  /// summaries and metrics are made from, cannot be skipped.
  std::set<std::string> skip;
  bool records(const std::string& file) const { return skip.count(file) == 0; }
};
/// The names `recorder.skip` takes.
inline constexpr const char* kSkippableFiles[] = {"commands", "wheels",  "v2v",          "gps",
                                                  "imu",      "compass", "wheel_speeds", "radar"};

/// How the launcher places the members of a run in processes (`processes:`, or syndds_plan
/// --processes; docs/deployment.md, "Processes"). The recorded results are byte-identical
/// whatever the layout; only the cost differs. The coordinator and the recorder always have a
/// process of their own, and so has a late-joining sensor (it may be started later).
struct ProcessLayout {
  enum class Kind {
    per_member,   // one process per member (default)
    per_vehicle,  // a vehicle, its controller and its sensors in one process
    groups,       // the vehicles, each with its members, spread over `groups` processes
  };
  Kind kind = Kind::per_member;
  int groups = 0;
  /// "per_member", "per_vehicle" or a whole number 1..999; nullopt otherwise.
  static std::optional<ProcessLayout> parse(const std::string& text);
  static constexpr const char* kExpected =
      "expected per_member, per_vehicle or a number of processes (1..999)";
  std::string to_string() const;
};

struct Scenario {
  std::string name;
  std::string file;
  std::uint64_t seed = 1;
  TimeConfig time;
  CoordinatorConfig coordinator;
  DdsConfig dds;
  WorldConfig world;
  TerrainConfig terrain;
  /// Obstacles given without z rest on the ground: their z is NaN in load_scenario_config
  /// and set by place_obstacles once the terrain is built.
  world::Obstacles obstacles;
  std::vector<VehicleConfig> vehicles;
  RecorderConfig recorder;
  CheckpointConfig checkpoint;
  ProcessLayout processes;
  /// Every file the scenario was read from (the scenario, vehicle files, rigs, soil presets,
  /// height-map images), in read order with its role and content hash.
  std::vector<ConfigFile> files;
  /// Hash of those files' roles and contents and of the overrides: every member must agree.
  std::uint64_t fingerprint = 0;

  const VehicleConfig* find_vehicle(const std::string& id) const;
  /// Every barrier member the scenario declares, in a fixed order.
  std::vector<std::string> member_ids() const;
  /// Members the run does not wait for at the start: they may join later (late_join).
  bool is_late_member(const std::string& member_id) const;
  /// The members each process of the run hosts under `layout` (besides the coordinator; the
  /// external controllers are the user's): vehicles' processes first, the recorder last.
  std::vector<std::vector<std::string>> process_members(const ProcessLayout& layout) const;
};

/// Command-line overrides applied on top of the file (they change the fingerprint too).
struct Overrides {
  std::optional<double> duration_s;
  std::optional<bool> realtime;
  std::optional<int> domain_id;
};

/// Where vehicle model names are looked up: $SYNDDS_CONFIG_DIR, else the source tree's config/.
std::string default_config_dir();

/// Reads and checks a scenario and every file it names; ConfigError naming file, line and key.
/// Obstacles without z keep a NaN z (load_scenario places them on the ground).
Scenario load_scenario_config(const std::string& file, const Overrides& overrides = {},
                              const std::string& config_dir = default_config_dir());
Scenario parse_scenario_config(const YamlNode& root, const std::string& text,
                               const Overrides& overrides, const std::string& config_dir);

// The world a scenario describes, for the processes that simulate: defined in the library
// syndds_scenario (scenario_world.cpp), which the coordinator and syndds_plan do not link.

/// The terrain surface a terrain block describes (for scm: a fresh, undeformed ScmTerrain).
std::shared_ptr<const terrain::TerrainSurface> make_terrain(const TerrainConfig& terrain);
/// Sets the z of the obstacles given without one: a sphere on its lowest point, a box or a
/// cylinder on its base, on the undeformed terrain.
void place_obstacles(Scenario& s);
/// load_scenario_config (parse_scenario_config), then place_obstacles.
Scenario load_scenario(const std::string& file, const Overrides& overrides = {},
                       const std::string& config_dir = default_config_dir());
Scenario parse_scenario(const YamlNode& root, const std::string& text, const Overrides& overrides,
                        const std::string& config_dir);

// Member ids: "vehicle/<id>", "controller/<id>", "external/<id>", "sensor/<id>", "recorder".
std::string vehicle_member(const std::string& vehicle_id);
std::string controller_member(const std::string& vehicle_id);
std::string external_member(const std::string& vehicle_id);
std::string sensor_member(const std::string& vehicle_id);
inline constexpr const char* kRecorderMember = "recorder";

/// Frames of `heartbeat_s` in `period_s` when it is a whole number of them (at least 1),
/// else nullopt: the policy controller's period rule.
std::optional<std::int64_t> whole_frames(double period_s, double heartbeat_s);

}  // namespace syndds::scenario
