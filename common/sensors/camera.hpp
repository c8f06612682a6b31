#pragma once
// Camera: pinhole with radial distortion, ray traced with Embree (16-ray packets over 4 x 4
// pixel blocks, 16 x 16 pixel tiles spread over a fixed thread pool).
//
// Frames: camera x forward, y left, z up (like a vehicle). Image u right, v down, pixel (u, v)
// covers [u, u+1) x [v, v+1). Normalised undistorted coordinates x_n = -y/x, y_n = -z/x;
// distortion (Brown-Conrady, radial): x_d = x_n (1 + k1 r^2 + k2 r^4), r^2 = x_n^2 + y_n^2;
// pixel = (f x_d + W/2, f y_d + H/2) with f = (W/2) / tan(hfov/2) (square pixels).
//
// Shading: albedo * (sun * max(0, n.l) * visible + ambient * (sky + bounce * ground)) with
// sky = (1 + n_z) / 2 and ground = (1 - n_z) / 2 (a hemisphere light with a ground bounce);
// visibility of the sun from a shadow ray (every object casts shadows, the sensor's own
// vehicle too); sky gradient for misses. Then display value
// v = clamp(gain * radiance)^(1/gamma), noise on v (Gaussian std, or pixel-dependent
// sigma = sqrt(slope v + intercept)), quantised to 8 bits.
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "core/thread_pool.hpp"
#include "sensors/interoceptive.hpp"
#include "sensors/scene.hpp"
#include "sensors/sensor_config.hpp"
#include "sensors/timing.hpp"

namespace syndds::sensors {

/// 8-bit RGB image, row-major, 3 bytes per pixel, row 0 at the top.
struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> pixels;
  const std::uint8_t* at(int u, int v) const {
    return &pixels[(static_cast<std::size_t>(v) * width + u) * 3];
  }
};

class CameraModel {
 public:
  /// Throws std::invalid_argument for sizes outside 16x9 .. 7680x4320 or hfov outside (0, 170 deg).
  explicit CameraModel(const CameraIntrinsics& intrinsics);
  const CameraIntrinsics& intrinsics() const { return intrinsics_; }
  double focal_px() const { return focal_; }
  /// Pixel coordinates (continuous) of a point in the camera frame; nullopt behind the camera.
  std::optional<Vec2> project(const Vec3& point_camera) const;
  /// Unit ray direction (camera frame) through continuous pixel coordinates (u, v).
  Vec3 ray_direction(double u, double v) const;

 private:
  CameraIntrinsics intrinsics_;
  double focal_;
};

/// Renders linear radiance (RGB floats in [0, ~1.2], row-major) with a fixed thread pool.
class CameraRenderer {
 public:
  CameraRenderer(const CameraIntrinsics& intrinsics, int threads);
  const CameraModel& model() const { return model_; }
  int threads() const { return pool_.size(); }
  ThreadPool& pool() { return pool_; }
  /// Renders the committed scene seen from `pose` (world; camera x forward). `radiance` holds
  /// width * height * 3 floats. `hidden_vehicle_slot` (Scene::vehicle_slot) is not seen.
  void render(const Scene& scene, const Pose& pose, std::span<float> radiance,
              int hidden_vehicle_slot = -1);

 private:
  CameraModel model_;
  ThreadPool pool_;
};

struct CameraFrame {
  std::string sensor_id;
  SampleStamp stamp;
  Pose pose;  // world pose of the camera at the (last) render
  RgbImage image;
};

/// Camera pose behind and above a vehicle (swung by chase.azimuth_deg about the vehicle's
/// vertical axis, positive towards its left), following its yaw only, looking at the vehicle
/// point target_height_m above its reference.
Pose chase_camera_pose(const Pose& vehicle, const ChaseConfig& chase);

/// The rate / lag / exposure / noise wrapper around a renderer. Feed it once per frame after
/// the scene holds that frame's state (and was committed).
class CameraSensor {
 public:
  /// `vehicle_id`: the vehicle it rides on (empty for mode fixed); `tick_s`: the interval
  /// update() is called at (the frame). Throws std::invalid_argument for an exposure window
  /// longer than the period or the lag.
  CameraSensor(const CameraConfig& config, std::string vehicle_id, std::uint64_t seed,
               double tick_s);
  void update(const Scene& scene, double time_s);
  std::vector<CameraFrame> take_available(double now_s);

  const CameraConfig& config() const { return config_; }
  const CameraModel& model() const { return renderer_.model(); }
  const SampleClock& clock() const { return clock_; }
  /// World pose of the camera for the scene's current vehicle poses.
  Pose camera_pose(const Scene& scene) const;
  /// Renders and finishes one image now (bypasses rate, lag and exposure); `noise_index`
  /// selects the noise pattern.
  RgbImage capture(const Scene& scene, std::uint64_t noise_index);
  /// Radiance -> 8-bit image with gamma and noise (noise pattern from `noise_index`).
  RgbImage finish(std::span<const float> radiance, std::uint64_t noise_index);
  std::size_t renders() const { return renders_; }

  /// Which frames to make (e.g. only those a consumer will read: the learning environment
  /// renders only the newest frame at each decision). Called when frame k is due with its
  /// available tick and the available tick of frame k + 1; false skips frame k: not rendered,
  /// never available. Frames made are the same as without a filter (the noise is a function of
  /// k). Not part of the checkpoint state; none by default.
  using FrameFilter = std::function<bool(std::int64_t available_tick, std::int64_t next_available_tick)>;
  void set_frame_filter(FrameFilter filter) { filter_ = std::move(filter); }
  std::size_t skipped() const { return skipped_; }
  /// Whether update(scene, time_s) renders (an instant of the open exposure has come, or a
  /// frame due now, that the filter wants, exposes at its trigger): the scene must be
  /// committed before such an update, not before others.
  bool may_render(double time_s) const;

  /// Checkpoint state (between frames): schedule, an exposure still open (its accumulated
  /// radiance), frames waiting for their lag (images included), the render counter. The
  /// renderer and the scene are not part of it (the scene is the caller's).
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  struct Capture {
    std::uint64_t k = 0;
    std::int64_t trigger_tick = 0;
    std::size_t next = 0;  // next entry of offsets_
    double weight = 0.0;
  };
  void advance(const Scene& scene, std::int64_t tick);
  int hidden_slot(const Scene& scene) const;

  CameraConfig config_;
  std::string vehicle_id_;
  std::uint64_t seed_;
  CameraRenderer renderer_;
  SampleClock clock_;
  std::vector<std::pair<std::int64_t, int>> offsets_;  // (tick offset, weight)
  std::optional<Capture> capture_;
  std::vector<float> frame_radiance_;
  std::vector<float> accum_;
  Pose last_pose_;
  FrameFilter filter_;
  std::size_t skipped_ = 0;
  LagQueue<CameraFrame> queue_;
  std::vector<float> gamma_lut_;
  std::size_t renders_ = 0;
};

}  // namespace syndds::sensors
