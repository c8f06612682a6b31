#include "sensors/rig_config.hpp"

#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>
#include <tuple>

namespace syndds::sensors {
namespace {

int integer(MapReader& m, std::string_view key, int fallback, int lo, int hi) {
  auto n = m.optional(key);
  if (!n) return fallback;
  const auto v = n->as_int();
  if (v < lo || v > hi) {
    n->fail("must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
            std::to_string(v));
  }
  return static_cast<int>(v);
}

double non_negative(MapReader& m, std::string_view key, double fallback) {
  return m.number(key, fallback, 0.0, 1e300);
}

// A number or a list of three numbers (per axis), each >= 0 unless `signed_values`.
Vec3 per_axis(const YamlNode& n, bool signed_values) {
  Vec3 v;
  if (n.is_scalar()) {
    v = Vec3::Constant(n.as_double());
  } else {
    const auto d = n.as_doubles(3);
    v = Vec3(d[0], d[1], d[2]);
  }
  if (!signed_values && v.minCoeff() < 0.0) n.fail("values must be >= 0");
  return v;
}

std::pair<double, double> range_pair(MapReader& m, std::string_view key,
                                     std::pair<double, double> fallback) {
  auto n = m.optional(key);
  if (!n) return fallback;
  const auto d = n->as_doubles(2);
  if (d[1] < d[0]) n->fail("expected [min, max] with min <= max");
  return {d[0], d[1]};
}

Mount parse_mount(const YamlNode& node) {
  MapReader m(node);
  Mount mount;
  if (auto p = m.optional("position_m")) {
    const auto d = p->as_doubles(3);
    mount.pose.position = Vec3(d[0], d[1], d[2]);
  }
  if (auto r = m.optional("rpy_deg")) {
    const auto d = r->as_doubles(3);
    // Roll about x, then pitch about y (positive looks down), then yaw about z.
    mount.pose.orientation = Quat(Eigen::AngleAxisd(deg_to_rad(d[2]), Vec3::UnitZ())) *
                             Quat(Eigen::AngleAxisd(deg_to_rad(d[1]), Vec3::UnitY())) *
                             Quat(Eigen::AngleAxisd(deg_to_rad(d[0]), Vec3::UnitX()));
  }
  m.finish();
  return mount;
}

// Noise block in the sensor's units: std (white noise per sample) or density_per_sqrt_hz
// (std = density * sqrt(rate)), walk_per_sqrt_s (bias random walk), initial_bias.
NoiseConfig parse_noise(const YamlNode& node, double rate_hz) {
  MapReader m(node);
  NoiseConfig n;
  auto white = m.optional("std");
  auto density = m.optional("density_per_sqrt_hz");
  if (white && density) density->fail("give either std or density_per_sqrt_hz, not both");
  if (white) n.white_std = per_axis(*white, false);
  if (density) n.white_std = per_axis(*density, false) * std::sqrt(rate_hz);
  if (auto w = m.optional("walk_per_sqrt_s")) n.walk_per_sqrt_s = per_axis(*w, false);
  if (auto b = m.optional("initial_bias")) n.initial_bias = per_axis(*b, true);
  m.finish();
  return n;
}

void parse_camera(MapReader& m, CameraConfig& c) {
  c.mode = [&] {
    const auto mode = m.choice("mode", std::string("mounted"), {"mounted", "chase", "fixed"});
    return mode == "mounted" ? CameraMode::mounted
                             : (mode == "chase" ? CameraMode::chase : CameraMode::fixed);
  }();
  if (auto ch = m.optional("chase")) {
    MapReader k(*ch);
    c.chase.distance_m = k.number("distance_m", c.chase.distance_m, 0.0, 1e4);
    c.chase.height_m = k.number("height_m", c.chase.height_m, -1e4, 1e4);
    c.chase.target_height_m = k.number("target_height_m", c.chase.target_height_m, -1e4, 1e4);
    c.chase.azimuth_deg = k.number("azimuth_deg", c.chase.azimuth_deg, -180.0, 180.0);
    k.finish();
  }
  c.intrinsics.width = integer(m, "width_px", c.intrinsics.width, 16, 7680);
  c.intrinsics.height = integer(m, "height_px", c.intrinsics.height, 9, 4320);
  c.intrinsics.hfov_rad =
      deg_to_rad(m.number("hfov_deg", rad_to_deg(c.intrinsics.hfov_rad), 1.0, 169.0));
  if (auto d = m.optional("distortion")) {
    MapReader k(*d);
    c.intrinsics.k1 = k.number("k1", 0.0, -1.0, 1.0);
    c.intrinsics.k2 = k.number("k2", 0.0, -1.0, 1.0);
    k.finish();
  }
  if (auto e = m.optional("exposure")) {
    MapReader k(*e);
    c.exposure_s = non_negative(k, "window_s", c.exposure_s);
    const auto mode = k.choice("mode", std::string("midpoint"), {"instant", "midpoint", "average"});
    c.exposure_mode = mode == "instant"
                          ? ExposureMode::instant
                          : (mode == "midpoint" ? ExposureMode::midpoint : ExposureMode::average);
    c.subframes = integer(k, "subframes", 1, 1, 64);
    k.finish();
  }
  c.gamma = m.number("gamma", c.gamma, 0.1, 10.0);
  c.gain = m.number("gain", c.gain, 0.0, 100.0);
  if (auto nz = m.optional("noise")) {
    MapReader k(*nz);
    const auto model = k.choice("model", std::nullopt, {"none", "gaussian", "pixel_dependent"});
    c.noise = model == "none" ? PixelNoiseModel::none
                              : (model == "gaussian" ? PixelNoiseModel::gaussian
                                                     : PixelNoiseModel::pixel_dependent);
    if (c.noise == PixelNoiseModel::gaussian) c.noise_std = k.number("std", std::nullopt, 0.0, 1.0);
    if (c.noise == PixelNoiseModel::pixel_dependent) {
      c.noise_slope = k.number("slope", std::nullopt, 0.0, 1.0);
      c.noise_intercept = k.number("intercept", std::nullopt, 0.0, 1.0);
    }
    k.finish();
  }
  c.hide_own_vehicle = m.get_or("hide_own_vehicle", c.hide_own_vehicle);
  c.threads = integer(m, "threads", c.threads, 1, 64);
  if (const auto error = config_error(c); !error.empty()) m.node().fail(error);
}

void parse_lidar(MapReader& m, LidarConfig& c) {
  c.channels = integer(m, "channels", c.channels, 1, 1024);
  c.samples = integer(m, "samples", c.samples, 1, 65535);
  std::tie(c.vfov_min_deg, c.vfov_max_deg) =
      range_pair(m, "vfov_deg", {c.vfov_min_deg, c.vfov_max_deg});
  std::tie(c.hfov_min_deg, c.hfov_max_deg) =
      range_pair(m, "hfov_deg", {c.hfov_min_deg, c.hfov_max_deg});
  std::tie(c.min_range_m, c.max_range_m) = range_pair(m, "range_m", {c.min_range_m, c.max_range_m});
  if (auto nz = m.optional("noise")) {
    MapReader k(*nz);
    c.range_noise_std_m = non_negative(k, "range_std_m", c.range_noise_std_m);
    c.angle_noise_std_rad = non_negative(k, "angle_std_rad", c.angle_noise_std_rad);
    k.finish();
  }
  if (auto b = m.optional("beam")) {
    MapReader k(*b);
    c.divergence_rad = k.number("divergence_rad", c.divergence_rad, 0.0, 0.5);
    c.beam_samples = integer(k, "samples", c.beam_samples, 1, 64);
    const auto mode = k.choice("return", std::string("nearest"), {"nearest", "strongest", "mean"});
    c.return_mode = mode == "nearest" ? LidarReturnMode::nearest
                                      : (mode == "strongest" ? LidarReturnMode::strongest
                                                             : LidarReturnMode::mean);
    k.finish();
  }
  c.hide_own_vehicle = m.get_or("hide_own_vehicle", c.hide_own_vehicle);
  c.threads = integer(m, "threads", c.threads, 1, 64);
  if (const auto error = config_error(c); !error.empty()) m.node().fail(error);
}

void parse_radar(MapReader& m, RadarConfig& c) {
  auto open_range = [&](std::string_view key, double& lo, double& hi) {
    std::tie(lo, hi) = range_pair(m, key, {lo, hi});
  };
  open_range("hfov_deg", c.hfov_min_deg, c.hfov_max_deg);
  open_range("vfov_deg", c.vfov_min_deg, c.vfov_max_deg);
  open_range("range_m", c.min_range_m, c.max_range_m);
  if (auto r = m.optional("rays")) {
    const auto d = r->as_doubles(2);
    for (double v : d) {
      if (v != std::floor(v) || v < 1 || v > 65535) r->fail("rays: [horizontal, vertical], whole numbers 1..65535");
    }
    c.horizontal_rays = static_cast<int>(d[0]);
    c.vertical_rays = static_cast<int>(d[1]);
  }
  if (auto k = m.optional("cluster")) {
    MapReader g(*k);
    c.range_gate_m = g.positive("range_gate_m", c.range_gate_m);
    c.speed_gate_mps = g.positive("speed_gate_mps", c.speed_gate_mps);
    c.min_points = integer(g, "min_points", c.min_points, 1, 1 << 20);
    g.finish();
  }
  c.min_strength_db = m.number("min_strength_db", c.min_strength_db, -400.0, 100.0);
  c.max_detections = integer(m, "max_detections", c.max_detections, 1, kMaxRadarDetections);
  c.ground = m.choice("ground", std::string("remove"), {"remove", "keep"}) == "keep"
                 ? RadarGround::keep
                 : RadarGround::remove;
  if (auto r = m.optional("reflectivity")) {
    // vehicle, terrain, other, and any obstacle label (rock, tree, ...).
    MapReader k(*r);
    c.reflectivity.vehicle = k.number("vehicle", c.reflectivity.vehicle, 0.0, 1e3);
    c.reflectivity.terrain = k.number("terrain", c.reflectivity.terrain, 0.0, 1e3);
    c.reflectivity.other = k.number("other", c.reflectivity.other, 0.0, 1e3);
    for (const auto& item : r->raw()) {
      const auto key = item.first.as<std::string>();
      if (key == "vehicle" || key == "terrain" || key == "other") continue;
      c.reflectivity.labels[key] = k.number(key, std::nullopt, 0.0, 1e3);
    }
    k.finish();
  }
  if (auto nz = m.optional("noise")) {
    MapReader k(*nz);
    c.range_noise_std_m = non_negative(k, "range_std_m", c.range_noise_std_m);
    c.azimuth_noise_std_rad = non_negative(k, "azimuth_std_rad", c.azimuth_noise_std_rad);
    c.elevation_noise_std_rad = non_negative(k, "elevation_std_rad", c.elevation_noise_std_rad);
    c.speed_noise_std_mps = non_negative(k, "speed_std_mps", c.speed_noise_std_mps);
    k.finish();
  }
  c.hide_own_vehicle = m.get_or("hide_own_vehicle", c.hide_own_vehicle);
  c.threads = integer(m, "threads", c.threads, 1, 64);
  if (const auto error = config_error(c); !error.empty()) m.node().fail(error);
}

SceneConfig parse_scene(const YamlNode& node) {
  MapReader m(node);
  SceneConfig s;
  s.sun_azimuth_deg = m.number("sun_azimuth_deg", s.sun_azimuth_deg, -360.0, 360.0);
  s.sun_elevation_deg = m.number("sun_elevation_deg", s.sun_elevation_deg, -90.0, 90.0);
  s.sun_intensity = static_cast<float>(m.number("sun_intensity", s.sun_intensity, 0.0, 10.0));
  s.ambient_intensity =
      static_cast<float>(m.number("ambient_intensity", s.ambient_intensity, 0.0, 10.0));
  s.ground_bounce = static_cast<float>(m.number("ground_bounce", s.ground_bounce, 0.0, 1.0));
  if (m.has("shadow_max_distance_m")) {
    s.shadow_max_distance_m = m.positive("shadow_max_distance_m", std::nullopt);
  }
  s.terrain_tile_cells = integer(m, "terrain_tile_cells", s.terrain_tile_cells, 4, 1024);
  s.cylinder_segments = integer(m, "cylinder_segments", s.cylinder_segments, 3, 256);
  if (m.has("meshes")) {
    // Relative to the rig file's folder (config/sensors/*.yaml: ../meshes).
    const YamlNode dir = m.required("meshes");
    std::filesystem::path p = dir.as<std::string>();
    if (p.is_relative()) p = std::filesystem::path(node.file()).parent_path() / p;
    if (!std::filesystem::is_directory(p)) dir.fail("no mesh directory " + p.lexically_normal().string());
    s.mesh_dir = p.lexically_normal().string();
  }
  m.finish();
  return s;
}

}  // namespace

SensorRig parse_sensor_rig(const YamlNode& root) {
  MapReader top(root);
  SensorRig rig;
  rig.file = root.file();
  rig.name = top.get<std::string>("name");
  if (auto g = top.optional("geodetic_origin")) {
    MapReader m(*g);
    rig.geodetic_origin.lat_deg = m.number("lat_deg", std::nullopt, -90.0, 90.0);
    rig.geodetic_origin.lon_deg = m.number("lon_deg", std::nullopt, -180.0, 180.0);
    rig.geodetic_origin.alt_m = m.number("alt_m", 0.0, -1e4, 1e5);
    m.finish();
  }
  if (auto s = top.optional("scene")) rig.scene = parse_scene(*s);
  std::set<std::string> ids;
  for (const YamlNode& item : top.required("sensors").elements()) {
    MapReader m(item);
    const std::string id = m.get<std::string>("id");
    if (!is_valid_sensor_id(id)) {
      m.required("id").fail("sensor id must be 1-32 characters of [A-Za-z0-9_.-] starting with a "
                            "letter or digit (it names CSV rows and files), got '" + id + "'");
    }
    if (!ids.insert(id).second) m.required("id").fail("duplicate sensor id '" + id + "'");
    const std::string type = m.choice(
        "type", std::nullopt, {"camera", "lidar", "radar", "gps", "imu", "magnetometer", "tachometer"});
    auto rate_and_lag = [&](double rate, double lag) {
      return std::pair{m.positive("rate_hz", rate), non_negative(m, "lag_s", lag)};
    };
    auto mount = [&](Mount fallback) {
      auto n = m.optional("mount");
      return n ? parse_mount(*n) : fallback;
    };
    if (type == "camera") {
      CameraConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.mount = mount(c.mount);
      parse_camera(m, c);
      rig.cameras.push_back(c);
    } else if (type == "lidar") {
      LidarConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.mount = mount(c.mount);
      parse_lidar(m, c);
      rig.lidars.push_back(c);
    } else if (type == "radar") {
      RadarConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.mount = mount(c.mount);
      parse_radar(m, c);
      rig.radars.push_back(c);
    } else if (type == "gps") {
      GpsConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.mount = mount(c.mount);
      const auto model = m.choice("model", std::string("wgs84"), {"wgs84", "wgs84_flat", "sphere"});
      c.model = model == "wgs84" ? GeodeticModel::wgs84
                                 : (model == "sphere" ? GeodeticModel::sphere
                                                      : GeodeticModel::wgs84_flat);
      if (auto n = m.optional("noise")) c.noise = parse_noise(*n, c.rate_hz);
      rig.gps.push_back(c);
    } else if (type == "imu") {
      ImuConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.mount = mount(c.mount);
      if (auto n = m.optional("accelerometer")) c.accelerometer = parse_noise(*n, c.rate_hz);
      if (auto n = m.optional("gyroscope")) c.gyroscope = parse_noise(*n, c.rate_hz);
      rig.imus.push_back(c);
    } else if (type == "magnetometer") {
      MagnetometerConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.mount = mount(c.mount);
      c.heading_noise_std_rad = non_negative(m, "heading_noise_std_rad", c.heading_noise_std_rad);
      if (auto f = m.optional("field")) {
        MapReader k(*f);
        c.field_strength_ut = k.number("strength_ut", c.field_strength_ut, 0.0, 1e4);
        c.declination_deg = k.number("declination_deg", c.declination_deg, -180.0, 180.0);
        c.inclination_deg = k.number("inclination_deg", c.inclination_deg, -90.0, 90.0);
        c.field_noise_std_ut = non_negative(k, "noise_std_ut", c.field_noise_std_ut);
        k.finish();
      }
      rig.magnetometers.push_back(c);
    } else {
      TachometerConfig c;
      c.id = id;
      std::tie(c.rate_hz, c.lag_s) = rate_and_lag(c.rate_hz, c.lag_s);
      c.noise_std_rad_s = non_negative(m, "noise_std_rad_s", c.noise_std_rad_s);
      rig.tachometers.push_back(c);
    }
    m.finish();
    rig.sensor_ids.push_back(id);
  }
  top.finish();
  return rig;
}

SensorRig load_sensor_rig(const std::string& file) {
  return parse_sensor_rig(YamlNode::load_file(file));
}

std::string sensor_rig_path(const std::string& name_or_path, const std::string& config_dir) {
  if (std::filesystem::is_regular_file(name_or_path)) return name_or_path;
  return (std::filesystem::path(config_dir) / "sensors" / (name_or_path + ".yaml")).string();
}

}  // namespace syndds::sensors
