#include "sensors/sensor_config.hpp"

#include <regex>

namespace syndds::sensors {

bool is_valid_sensor_id(const std::string& id) {
  static const std::regex pattern("[A-Za-z0-9][A-Za-z0-9_.-]{0,31}");
  return std::regex_match(id, pattern);
}

// The same limits LidarRenderer and CameraModel enforce when they are built, here without
// building them.
std::string config_error(const LidarConfig& c) {
  if (c.channels < 1 || c.channels > 1024 || c.samples < 1 || c.samples > 65535) {
    return "channels must be 1..1024, samples 1..65535";
  }
  if (!(c.max_range_m > c.min_range_m) || c.min_range_m < 0.0) {
    return "need 0 <= min_range_m < max_range_m";
  }
  if (c.vfov_max_deg < c.vfov_min_deg || c.hfov_max_deg < c.hfov_min_deg ||
      c.hfov_max_deg - c.hfov_min_deg > 360.0 + 1e-9 || c.vfov_min_deg < -90.0 ||
      c.vfov_max_deg > 90.0) {
    return "bad field of view";
  }
  if (c.beam_samples < 1 || c.beam_samples > 64) return "beam samples must be 1..64";
  const std::int64_t rays = std::int64_t{c.channels} * c.samples * c.beam_samples;
  if (rays > kMaxLidarRaysPerScan) {
    return std::to_string(c.channels) + " channels x " + std::to_string(c.samples) +
           " samples x " + std::to_string(c.beam_samples) + " beam samples make " +
           std::to_string(rays) + " rays per scan; the budget is " +
           std::to_string(kMaxLidarRaysPerScan) + " (docs/sensors.md, Budgets)";
  }
  return "";
}

std::string config_error(const RadarConfig& c) {
  if (c.horizontal_rays < 1 || c.vertical_rays < 1 || c.horizontal_rays > 65535 ||
      c.vertical_rays > 65535) {
    return "radar rays must be 1..65535 in each direction";
  }
  if (!(c.max_range_m > c.min_range_m) || c.min_range_m < 0.0) {
    return "need 0 <= min_range_m < max_range_m";
  }
  if (!(c.hfov_max_deg > c.hfov_min_deg) || c.hfov_max_deg - c.hfov_min_deg > 360.0 + 1e-9 ||
      !(c.vfov_max_deg > c.vfov_min_deg) || c.vfov_min_deg < -90.0 || c.vfov_max_deg > 90.0) {
    return "bad field of view (need min < max, at most 360 degrees across, elevations in "
           "[-90, 90])";
  }
  if (!(c.range_gate_m > 0.0) || !(c.speed_gate_mps > 0.0)) {
    return "cluster gates must be > 0";
  }
  if (c.min_points < 1) return "cluster min_points must be >= 1";
  if (c.max_detections < 1 || c.max_detections > kMaxRadarDetections) {
    return "max_detections must be 1.." + std::to_string(kMaxRadarDetections);
  }
  const std::int64_t rays = std::int64_t{c.horizontal_rays} * c.vertical_rays;
  if (rays > kMaxRadarRaysPerScan) {
    return std::to_string(c.horizontal_rays) + " x " + std::to_string(c.vertical_rays) +
           " rays make " + std::to_string(rays) + " rays per scan; the budget is " +
           std::to_string(kMaxRadarRaysPerScan) + " (docs/sensors.md, Budgets)";
  }
  return "";
}

std::string config_error(const CameraConfig& c) {
  const auto& in = c.intrinsics;
  if (in.width < 16 || in.height < 9 || in.width > 7680 || in.height > 4320) {
    return "camera resolution must be within 16x9 .. 7680x4320";
  }
  if (!(in.hfov_rad > 0.0) || in.hfov_rad >= deg_to_rad(170.0)) {
    return "camera hfov must be in (0, 170) degrees";
  }
  const double focal = 0.5 * in.width / std::tan(0.5 * in.hfov_rad);
  // Distortion must stay monotonic over the image (else the inverse is ambiguous).
  const double half_diag = 0.5 * std::hypot(in.width, in.height) / focal * 1.5;
  for (int i = 1; i <= 100; ++i) {
    const double r = half_diag * i / 100.0, r2 = r * r;
    if (1.0 + 3.0 * in.k1 * r2 + 5.0 * in.k2 * r2 * r2 <= 0.0) {
      return "camera distortion (k1, k2) folds the image over";
    }
  }
  const int renders = c.exposure_mode == ExposureMode::average ? c.subframes : 1;
  const std::int64_t pixels = std::int64_t{in.width} * in.height * renders;
  if (renders < 1 || pixels > kMaxCameraPixelsPerFrame) {
    return std::to_string(in.width) + " x " + std::to_string(in.height) + " pixels x " +
           std::to_string(renders) + " exposure subframes make " + std::to_string(pixels) +
           " pixels per frame; the budget is " + std::to_string(kMaxCameraPixelsPerFrame) +
           " (docs/sensors.md, Budgets)";
  }
  return "";
}

}  // namespace syndds::sensors
