#pragma once
// Radar: a grid of rays over the field of view, ray traced with Embree in the same scene as the
// camera and lidar, reduced to detections as an automotive radar reports them
// (docs/sensors.md, "Radar").
//
// Rays: horizontal_rays x vertical_rays at the centres of equal cells of the field of view
// (azimuth from x towards y, elevation up; sensor frame x forward, y left, z up); ray (h, v) is
// number h * vertical_rays + v and stands for the solid angle dOmega = dAz dEl cos(el) of its cell.
//
// Return of a ray that hits within [min_range, max_range] at range r, incidence theta, on a
// surface of radar reflectivity rho (RadarReflectivity: vehicles, terrain, obstacles by label):
//   cross-section sigma = rho |cos theta| r^2 dOmega     (the area the ray stands for, weighted)
//   power        p     = sigma / r^4                     (radar equation, re 1 m^2 at 1 m)
//   radial speed       = (v_point - v_sensor) . u        (u: unit ray direction; > 0 opening)
// where v_point is the rigid chassis motion of a vehicle hit (wheel spin not added) and zero
// for terrain and obstacles, and v_sensor the motion of the sensor's mount on its vehicle.
// Ground rule: `remove` drops every return from the terrain before clustering (the effect of a
// radar's ground-clutter filter); `keep` clusters them like any other surface.
//
// Detections: returns of neighbouring rays (the 8-neighbourhood of the ray grid) whose ranges
// differ by at most range_gate_m and radial speeds by at most speed_gate_mps are one cluster
// (connected components; deterministic). A cluster with at least min_points returns is a
// detection: strength = 10 log10(sum p), rcs = 10 log10(sum sigma) (so an object resolved by
// many rays has strength rcs - 40 log10 r), position and radial speed power-weighted means.
// Detections weaker than min_strength_db are dropped, the max_detections strongest kept, then
// ordered by range (ties: first ray). Noise (Gaussian, on range, azimuth, elevation and radial
// speed of each detection) is a pure function of (seed, scan index, detection index).
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "core/thread_pool.hpp"
#include "sensors/scene.hpp"
#include "sensors/sensor_config.hpp"
#include "sensors/timing.hpp"

namespace syndds::sensors {

struct RadarDetection {
  float x = 0, y = 0, z = 0;  // centroid, sensor frame, metres
  float range_m = 0;
  float azimuth_rad = 0;    // from x towards y
  float elevation_rad = 0;  // up
  float radial_speed_mps = 0;  // range rate: > 0 moving away
  float strength_db = 0;       // received power re a 1 m^2 target at 1 m
  float rcs_dbsm = 0;          // radar cross-section, dB re 1 m^2
  std::uint32_t points = 0;    // returns clustered

  template <typename Archive>
  void state(Archive& a) {
    a.io(x);
    a.io(y);
    a.io(z);
    a.io(range_m);
    a.io(azimuth_rad);
    a.io(elevation_rad);
    a.io(radial_speed_mps);
    a.io(strength_db);
    a.io(rcs_dbsm);
    a.io(points);
  }
  void state(core::StateWriter& w) const {
    const_cast<RadarDetection*>(this)->state<core::StateWriter>(w);
  }
};

struct RadarScan {
  std::string sensor_id;
  SampleStamp stamp;
  Pose pose;                       // world pose of the sensor
  Vec3 velocity = Vec3::Zero();    // world velocity of the sensor
  std::vector<RadarDetection> detections;

  template <typename Archive>
  void state(Archive& a) {
    a.io(sensor_id);
    a.io(stamp);
    a.io(pose.position);
    a.io(pose.orientation);
    a.io(velocity);
    a.io(detections);
  }
  void state(core::StateWriter& w) const { const_cast<RadarScan*>(this)->state<core::StateWriter>(w); }
};

/// The noiseless return of one ray (range <= 0: none, or a ground return removed).
struct RadarReturn {
  float range = -1.0f;
  float x = 0, y = 0, z = 0;  // sensor frame
  float radial_speed = 0.0f;
  float power = 0.0f;  // sigma / r^4
  float rcs = 0.0f;    // sigma, m^2
  SurfaceKind kind = SurfaceKind::terrain;
};

class RadarSensor {
 public:
  /// Throws std::invalid_argument for a configuration config_error() refuses.
  RadarSensor(const RadarConfig& config, std::string vehicle_id, std::uint64_t seed, double tick_s);
  /// Feed once per frame after the scene holds that frame's state (committed).
  void update(const Scene& scene, double time_s);
  std::vector<RadarScan> take_available(double now_s);
  /// Scans now (bypasses rate and lag); `noise_index` selects the noise draw.
  RadarScan scan(const Scene& scene, std::uint64_t noise_index);
  /// The returns of the last scan, ray by ray (h * vertical_rays + v).
  const std::vector<RadarReturn>& returns() const { return returns_; }
  Pose sensor_pose(const Scene& scene) const;
  Vec3 sensor_velocity(const Scene& scene, const Pose& pose) const;
  const RadarConfig& config() const { return config_; }
  int rays() const { return config_.horizontal_rays * config_.vertical_rays; }
  double azimuth_rad(int h) const;
  double elevation_rad(int v) const;

  /// Checkpoint state (between frames): the schedule and the scans waiting for their lag.
  template <typename Archive>
  void state(Archive& a);
  void save_state(core::StateWriter& w) const { const_cast<RadarSensor*>(this)->state(w); }
  void load_state(core::StateReader& r) { state(r); }

 private:
  void trace(const Scene& scene, const Pose& pose, const Vec3& sensor_velocity, int hidden_slot);
  void cluster(std::vector<RadarDetection>& out);

  RadarConfig config_;
  std::string vehicle_id_;
  std::uint64_t seed_;
  ThreadPool pool_;
  SampleClock clock_;
  LagQueue<RadarScan> queue_;
  std::vector<float> directions_;  // per ray, sensor frame xyz
  std::vector<float> solid_angle_;  // per ray, steradians
  std::vector<RadarReturn> returns_;
  std::vector<std::uint32_t> parent_;  // union-find over rays
};

}  // namespace syndds::sensors
