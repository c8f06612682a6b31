#pragma once
// Plain configuration of the sensors of a rig (docs/sensors.md): what a rig file says, with
// no renderer, scene or noise stream behind it. Readers and budget checks live in
// rig_config.hpp; the sensors themselves (camera.hpp, lidar.hpp, radar.hpp, interoceptive.hpp) are built
// from these structs only by the processes that simulate them.
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <string>

#include "core/math.hpp"
#include "sensors/geodesy.hpp"

namespace syndds::sensors {

/// Linear RGB in [0, 1] (albedo or radiance).
struct Rgb {
  float r = 0.0f, g = 0.0f, b = 0.0f;
  friend bool operator==(const Rgb&, const Rgb&) = default;
};

struct SceneConfig {
  double sun_azimuth_deg = 135.0;  // compass azimuth of the sun (clockwise from north)
  double sun_elevation_deg = 50.0;
  float sun_intensity = 0.85f;
  float ambient_intensity = 0.3f;  // sky light on an upward surface (half on a vertical one)
  float ground_bounce = 0.3f;      // share of the ambient light reaching downward surfaces
  Rgb sky_horizon{0.78f, 0.86f, 0.95f};
  Rgb sky_zenith{0.35f, 0.55f, 0.88f};
  double shadow_max_distance_m = std::numeric_limits<double>::infinity();
  float obstacle_reflectance = 0.5f;
  int terrain_tile_cells = 64;  // tile = 64 x 64 cells (8192 triangles)
  int cylinder_segments = 32;
  int embree_threads = 0;  // BVH build threads (0: Embree's default)
  // Directory of OBJ meshes (empty: primitives only): an obstacle labelled L is drawn with
  // L.obj when it exists, vehicle bodies with vehicle_body.obj (docs/sensors.md "Meshes").
  std::string mesh_dir;
  // The content hash (FNV-1a 64; 0: absent) of each mesh by name, as the scenario's fingerprint
  // has it (scenario loading fills it): a mesh whose bytes differ when it is drawn is an error,
  // never another shape. Empty: not checked (a scene built without a scenario).
  std::map<std::string, std::uint64_t> mesh_hashes;

  /// Unit vector towards the sun (world ENU).
  Vec3 sun_direction() const;
};


/// Gaussian white noise plus a random-walk bias, per axis:
///   bias_{k+1} = bias_k + N(0, walk * sqrt(dt)),  value = truth + bias + N(0, white_std).
struct NoiseConfig {
  Vec3 white_std = Vec3::Zero();
  Vec3 walk_per_sqrt_s = Vec3::Zero();  // random-walk density (units / sqrt(s))
  Vec3 initial_bias = Vec3::Zero();
};

/// Sensor placement on the chassis reference frame (x forward, y left, z up).
struct Mount {
  Pose pose;
};

struct GpsConfig {
  std::string id = "gps";
  double rate_hz = 10.0;
  double lag_s = 0.1;
  Mount mount;  // antenna position (orientation unused)
  GeodeticModel model = GeodeticModel::wgs84;
  NoiseConfig noise;  // on the ENU position, metres
};

struct ImuConfig {
  std::string id = "imu";
  double rate_hz = 100.0;
  double lag_s = 0.0;
  Mount mount;
  NoiseConfig accelerometer;  // m/s2
  NoiseConfig gyroscope;      // rad/s
};

struct MagnetometerConfig {
  std::string id = "compass";
  double rate_hz = 50.0;
  double lag_s = 0.0;
  Mount mount;
  double heading_noise_std_rad = 0.0;
  double field_strength_ut = 50.0;  // Earth's field magnitude (microtesla)
  double declination_deg = 0.0;     // magnetic north east of true north
  double inclination_deg = 60.0;    // dip below the horizontal
  double field_noise_std_ut = 0.0;
};

struct TachometerConfig {
  std::string id = "tachometer";
  double rate_hz = 100.0;
  double lag_s = 0.0;
  double noise_std_rad_s = 0.0;
};

struct CameraIntrinsics {
  int width = 80;
  int height = 45;
  double hfov_rad = deg_to_rad(90.0);
  double k1 = 0.0;
  double k2 = 0.0;
};

enum class CameraMode { mounted, chase, fixed };
enum class ExposureMode { instant, midpoint, average };
enum class PixelNoiseModel { none, gaussian, pixel_dependent };

struct ChaseConfig {
  double distance_m = 8.0;       // from the vehicle, horizontally
  double height_m = 3.0;         // above the chassis reference point
  double target_height_m = 1.0;  // the camera looks at this point above the reference
  // Swing about the vehicle's vertical axis: 0 straight behind, positive towards the vehicle's
  // left (90: on its left, looking at its side), negative towards its right.
  double azimuth_deg = 0.0;
};

struct CameraConfig {
  std::string id = "camera";
  double rate_hz = 30.0;
  double lag_s = 0.05;
  Mount mount;  // mounted: on the chassis; fixed: world pose
  CameraIntrinsics intrinsics;
  CameraMode mode = CameraMode::mounted;
  ChaseConfig chase;
  // Exposure (collection window) [t_k, t_k + exposure_s]: instant renders at t_k; midpoint
  // renders once at the tick nearest t_k + exposure/2; average renders `subframes` times at
  // the ticks nearest t_k + exposure (i + 0.5) / N and averages the radiance (motion blur).
  double exposure_s = 0.02;
  ExposureMode exposure_mode = ExposureMode::midpoint;
  int subframes = 1;
  double gamma = 2.2;
  double gain = 1.0;
  PixelNoiseModel noise = PixelNoiseModel::gaussian;
  double noise_std = 0.0004;  // on display values in [0, 1]
  double noise_slope = 0.0;   // pixel-dependent: sigma^2 = slope v + intercept
  double noise_intercept = 0.0;
  bool hide_own_vehicle = true;  // ignored in chase mode (the vehicle is the subject)
  int threads = 1;
};

enum class LidarReturnMode { nearest, strongest, mean };

struct LidarConfig {
  std::string id = "lidar";
  double rate_hz = 10.0;
  double lag_s = 0.1;
  Mount mount;
  int channels = 16;
  int samples = 900;
  double vfov_min_deg = -15.0;
  double vfov_max_deg = 15.0;
  double hfov_min_deg = -180.0;
  double hfov_max_deg = 180.0;
  double min_range_m = 0.3;
  double max_range_m = 100.0;
  double range_noise_std_m = 0.01;
  double angle_noise_std_rad = 0.001;
  double divergence_rad = 0.003;
  int beam_samples = 1;  // 1: one ray per beam (divergence ignored)
  LidarReturnMode return_mode = LidarReturnMode::nearest;
  bool hide_own_vehicle = true;
  int threads = 1;
};

enum class RadarGround { remove, keep };

/// Radar reflectivity (dimensionless, the share of the incident power a surface sends back
/// towards the radar at normal incidence) by what a ray hits: vehicles, the terrain, and
/// obstacles by label (docs/sensors.md, "Radar").
struct RadarReflectivity {
  double vehicle = 1.0;   // metal bodies
  double terrain = 0.02;  // soil, snow
  std::map<std::string, double> labels{{"rock", 0.3}, {"tree", 0.1}, {"bush", 0.05},
                                       {"wall", 0.5}};
  double other = 0.3;  // an obstacle whose label is not listed

  double of_obstacle(const std::string& label) const {
    const auto it = labels.find(label);
    return it == labels.end() ? other : it->second;
  }
};

/// Radar (docs/sensors.md, "Radar"): a grid of rays over the field of view (cell centres),
/// returns clustered into detections over the ray grid, the radar equation for strength.
struct RadarConfig {
  std::string id = "radar";
  double rate_hz = 20.0;
  double lag_s = 0.05;
  Mount mount;
  double hfov_min_deg = -10.0;
  double hfov_max_deg = 10.0;
  double vfov_min_deg = -2.5;
  double vfov_max_deg = 2.5;
  int horizontal_rays = 200;  // across the horizontal field of view
  int vertical_rays = 50;
  double min_range_m = 0.5;
  double max_range_m = 150.0;
  // Clustering: neighbouring rays (8-neighbourhood of the ray grid) whose returns differ by at
  // most these join one detection; a detection needs min_points returns.
  double range_gate_m = 4.0;
  double speed_gate_mps = 0.5;
  int min_points = 1;
  double min_strength_db = -90.0;  // received power re a 1 m2 target at 1 m
  int max_detections = 128;        // the strongest are kept
  RadarGround ground = RadarGround::remove;
  RadarReflectivity reflectivity;
  double range_noise_std_m = 0.0;
  double azimuth_noise_std_rad = 0.0;
  double elevation_noise_std_rad = 0.0;
  double speed_noise_std_mps = 0.0;
  bool hide_own_vehicle = true;
  int threads = 1;
};

// Budgets: the work one sensor may ask for per scan or frame, so that a rig within them
// renders within the frame deadline and no process allocates in proportion to a number it
// has not checked (docs/sensors.md, "Budgets").
/// Rays of one lidar scan: channels x samples x beam sub-rays. 2^21 is 8 times an Ouster
/// OS1-128 in its 2048 x 128 mode, 73 times a Velodyne VLP-16 at 0.2 degrees (16 x 1800).
inline constexpr std::int64_t kMaxLidarRaysPerScan = std::int64_t{1} << 21;
/// Rays of one radar scan: horizontal x vertical rays; a 0.02 degree grid over 40 x 10 degrees.
inline constexpr std::int64_t kMaxRadarRaysPerScan = std::int64_t{1} << 20;
/// Detections one radar scan may report (automotive radars report 64 to a few hundred).
inline constexpr int kMaxRadarDetections = 4096;
/// Rays of one camera frame: width x height x exposure subframes; one 8K UHD image.
inline constexpr std::int64_t kMaxCameraPixelsPerFrame = std::int64_t{7680} * 4320;
/// Sensor ids name CSV rows, DDS keys and files: a letter or digit, then letters, digits,
/// '_', '.', '-' (at most 32 characters).
bool is_valid_sensor_id(const std::string& id);

/// Why a lidar or camera configuration cannot be built ("" if it can): geometry and budgets,
/// checked in constant time (the renderers allocate per ray only when they are built).
std::string config_error(const LidarConfig& config);
std::string config_error(const CameraConfig& config);
std::string config_error(const RadarConfig& config);

}  // namespace syndds::sensors
