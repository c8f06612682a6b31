#pragma once
// Lidar: channels x horizontal samples of beams from a mounting pose, ray traced with Embree
// (16-ray packets along consecutive beams). Sensor frame: x forward, y left, z up; azimuth
// from x towards y, elevation up. Channel c sits at vfov_min + c * (vfov_max - vfov_min) /
// (channels - 1); sample s at hfov_min + s * span / samples for a full turn (no duplicate),
// else span / (samples - 1).
//
// Per beam: optional divergence (beam_samples sub-rays: the centre plus a ring at half the
// divergence angle), reduced by return mode (nearest, strongest intensity, or mean range);
// intensity = reflectance of the surface * |cos(incidence)| (mean mode: summed over sub-rays
// / beam_samples). Noise: Gaussian on the range and on the reported azimuth and elevation,
// a pure function of (seed, scan index, beam), hence identical for any thread count.
// A scan is taken at one instant (no rolling-shutter motion within the turn).
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "core/thread_pool.hpp"
#include "sensors/interoceptive.hpp"
#include "sensors/scene.hpp"
#include "sensors/sensor_config.hpp"
#include "sensors/timing.hpp"

namespace syndds::sensors {

struct LidarPoint {
  float x = 0, y = 0, z = 0;  // sensor frame, metres
  float intensity = 0;        // [0, 1]
  float range = 0;            // metres
  std::uint16_t channel = 0;
  std::uint16_t sample = 0;
};

struct LidarScan {
  std::string sensor_id;
  SampleStamp stamp;
  Pose pose;  // world pose of the sensor
  int channels = 0;
  int samples = 0;
  std::vector<LidarPoint> points;  // beams with a return, in (sample, channel) order
};

/// Noiseless return of one beam (range <= 0: nothing within range).
struct BeamReturn {
  float range = 0.0f;
  float intensity = 0.0f;
};

class LidarRenderer {
 public:
  /// Throws std::invalid_argument for a malformed geometry (channels, samples, ranges).
  explicit LidarRenderer(const LidarConfig& config);
  int beams() const { return config_.channels * config_.samples; }
  double elevation_rad(int channel) const;
  double azimuth_rad(int sample) const;
  /// Traces every beam from `pose`; out[sample * channels + channel].
  void render(const Scene& scene, const Pose& pose, std::vector<BeamReturn>& out,
              int hidden_vehicle_slot = -1);
  double cos_elevation(int channel) const { return cos_el_[static_cast<std::size_t>(channel)]; }
  double sin_elevation(int channel) const { return sin_el_[static_cast<std::size_t>(channel)]; }
  double cos_azimuth(int sample) const { return cos_az_[static_cast<std::size_t>(sample)]; }
  double sin_azimuth(int sample) const { return sin_az_[static_cast<std::size_t>(sample)]; }
  ThreadPool& pool() { return pool_; }

 private:
  LidarConfig config_;
  ThreadPool pool_;
  std::vector<double> cos_el_, sin_el_, cos_az_, sin_az_;
  std::vector<float> directions_;  // per ray (beam-major, sub-rays inner), sensor frame xyz
  std::vector<float> hits_range_;
  std::vector<float> hits_intensity_;
};

class LidarSensor {
 public:
  LidarSensor(const LidarConfig& config, std::string vehicle_id, std::uint64_t seed, double tick_s);
  /// Feed once per frame after the scene holds that frame's state (committed).
  void update(const Scene& scene, double time_s);
  std::vector<LidarScan> take_available(double now_s);
  /// Scans now (bypasses rate and lag); `noise_index` selects the noise draw.
  LidarScan scan(const Scene& scene, std::uint64_t noise_index);
  Pose sensor_pose(const Scene& scene) const;
  const LidarConfig& config() const { return config_; }
  const LidarRenderer& renderer() const { return renderer_; }

  /// Checkpoint state (between frames): schedule and scans waiting for their lag. The noise is
  /// a pure function of (seed, scan index, beam): no stream to keep.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  LidarConfig config_;
  std::string vehicle_id_;
  std::uint64_t seed_;
  LidarRenderer renderer_;
  SampleClock clock_;
  LagQueue<LidarScan> queue_;
  std::vector<BeamReturn> returns_;
  std::vector<LidarPoint> points_;
};

}  // namespace syndds::sensors
