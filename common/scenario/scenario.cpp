#include "scenario/scenario.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <tuple>

#include "core/hash.hpp"
#include "protocol/messages.hpp"

#ifndef SYNDDS_DEFAULT_CONFIG_DIR
#define SYNDDS_DEFAULT_CONFIG_DIR "config"
#endif

namespace syndds::scenario {
namespace fs = std::filesystem;
namespace {

TimeConfig parse_time(const YamlNode& node) {
  MapReader m(node);
  TimeConfig t;
  auto step = m.optional("step_s");
  t.step_s = m.positive("step_s", t.step_s);
  auto hb = m.optional("heartbeat_s");
  t.heartbeat_s = m.positive("heartbeat_s", t.heartbeat_s);
  t.end_time_s = m.positive("end_time_s", std::nullopt);
  if (t.end_time_s > kMaxEndTimeS) {
    std::ostringstream msg;
    msg << "must be in (0, " << kMaxEndTimeS << "] seconds, got " << t.end_time_s;
    m.required("end_time_s").fail(msg.str());
  }
  t.realtime = m.get_or("realtime", false);
  m.finish();
  const double ratio = t.heartbeat_s / t.step_s;
  const double n = std::round(ratio);
  if (n < 1.0 || std::abs(ratio - n) > 1e-9 * ratio) {
    std::ostringstream msg;
    msg << "heartbeat_s (" << t.heartbeat_s << ") must be a whole multiple of step_s ("
        << t.step_s << ")";
    (hb ? *hb : (step ? *step : node)).fail(msg.str());
  }
  if (n > static_cast<double>(kMaxStepsPerFrame)) {
    std::ostringstream msg;
    msg << "heartbeat_s / step_s is " << n << " dynamics steps per frame; at most "
        << kMaxStepsPerFrame;
    (hb ? *hb : (step ? *step : node)).fail(msg.str());
  }
  return t;
}

CoordinatorConfig parse_coordinator(const YamlNode& node) {
  MapReader m(node);
  CoordinatorConfig c;
  // Bounded so that deadlines stay representable on the steady clock (1e300 s wrapped).
  c.join_timeout_s = m.number("join_timeout_s", c.join_timeout_s, 0.001, kMaxTimeoutS);
  c.frame_timeout_s = m.number("frame_timeout_s", c.frame_timeout_s, 0.001, kMaxTimeoutS);
  const std::string policy =
      m.choice("on_member_loss", "abort", {"abort", "continue", "recover"});
  c.on_member_loss = policy == "abort"      ? proto::LossPolicy::abort
                     : policy == "continue" ? proto::LossPolicy::continue_run
                                            : proto::LossPolicy::recover;
  c.max_recoveries = static_cast<int>(m.number("max_recoveries", c.max_recoveries, 0, 1000));
  c.rejoin_timeout_s = m.number("rejoin_timeout_s", c.rejoin_timeout_s, 0.001, kMaxTimeoutS);
  m.finish();
  return c;
}

DdsConfig parse_dds(const YamlNode& node) {
  MapReader m(node);
  DdsConfig d;
  d.domain_id = static_cast<int>(m.number("domain_id", 0, 0, 232));
  d.transport = m.choice("transport", "default", {"default", "udp", "udp_redundant"});
  d.discovery_server = m.get_or<std::string>("discovery_server", "");
  if (!d.discovery_server.empty() &&
      !std::regex_match(d.discovery_server, std::regex(R"([0-9.]+:[0-9]+)"))) {
    m.required("discovery_server").fail("expected IPv4ADDR:PORT, e.g. 10.0.0.1:11811");
  }
  if (auto n = m.optional("security")) {
    MapReader sec(*n);
    const bool enabled = sec.get_or("enabled", true);
    const std::string dir = sec.get_or<std::string>("dir", "security");
    if (enabled) {
      d.security_dir = (fs::path(node.file()).parent_path() / dir).lexically_normal().string();
    }
    sec.finish();
  }
  m.finish();
  return d;
}

// Width and height from a PNG's IHDR chunk (bytes 16..23, big endian), if `bytes` is a PNG.
std::optional<std::pair<std::uint32_t, std::uint32_t>> png_size(const std::string& bytes) {
  static const char signature[] = "\x89PNG\r\n\x1a\n";
  if (bytes.size() < 24 || bytes.compare(0, 8, signature, 8) != 0 ||
      bytes.compare(12, 4, "IHDR") != 0) {
    return std::nullopt;
  }
  auto be32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    for (std::size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
    return v;
  };
  return std::pair{be32(16), be32(20)};
}

WorldConfig parse_world(const YamlNode& node) {
  MapReader m(node);
  WorldConfig w;
  const double lim = kMaxWorldCoordinateM;
  w.x_min_m = m.number("x_min_m", w.x_min_m, -lim, lim);
  w.x_max_m = m.number("x_max_m", w.x_max_m, -lim, lim);
  w.y_min_m = m.number("y_min_m", w.y_min_m, -lim, lim);
  w.y_max_m = m.number("y_max_m", w.y_max_m, -lim, lim);
  m.finish();
  for (const auto& [lo, hi, axis] : {std::tuple{w.x_min_m, w.x_max_m, "x"},
                                     std::tuple{w.y_min_m, w.y_max_m, "y"}}) {
    if (!(hi > lo) || hi - lo > kMaxWorldSideM) {
      std::ostringstream msg;
      msg << "the world's " << axis << " extent [" << lo << ", " << hi
          << "] must be non-empty and at most " << kMaxWorldSideM << " m";
      node.fail(msg.str());
    }
  }
  return w;
}

// Every position a scenario gives must lie in its world box (the renderers and the soil
// allocate in proportion to the area the positions span).
void check_in_world(const YamlNode& where, const WorldConfig& w, double x, double y) {
  if (w.contains(x, y)) return;
  std::ostringstream msg;
  msg << "(" << x << ", " << y << ") is outside the world [" << w.x_min_m << ", " << w.x_max_m
      << "] x [" << w.y_min_m << ", " << w.y_max_m << "] (declare a larger `world:` box, "
      << "at most " << kMaxWorldSideM << " m a side; docs/scenario.md)";
  where.fail(msg.str());
}

TerrainConfig parse_terrain(const YamlNode& node, const std::string& config_dir,
                            ConfigFiles& files) {
  MapReader m(node);
  TerrainConfig t;
  t.type = m.choice("type", "rigid", {"rigid", "heightmap", "scm"});
  if (t.type == "scm") {
    // The SCM reader owns the whole block (preset, soil, area, spacing, bulldozing...).
    t.scm = scm::parse_scm_params(node, (fs::path(config_dir) / "terrain").string(), &files);
    const auto& g = t.scm.grid;
    const double vertices =
        (std::floor(g.x_max_m / g.spacing_m) - std::ceil(g.x_min_m / g.spacing_m) + 1) *
        (std::floor(g.y_max_m / g.spacing_m) - std::ceil(g.y_min_m / g.spacing_m) + 1);
    if (vertices > kMaxScmVertices) {
      std::ostringstream msg;
      msg << "the soil patch (area / spacing_m) has " << vertices << " grid vertices; at most "
          << kMaxScmVertices << " (a larger spacing_m or a smaller area)";
      node.fail(msg.str());
    }
    t.friction = std::tan(deg_to_rad(t.scm.soil.friction_angle_deg));
    return t;
  }
  if (auto c = m.optional("colour")) {
    const auto rgb = c->as_doubles(3);
    for (double v : rgb) {
      if (!(v >= 0.0 && v <= 1.0)) c->fail("colour components must be in [0, 1]");
    }
    t.colour = std::array<double, 3>{rgb[0], rgb[1], rgb[2]};
  }
  if (t.type == "rigid") {
    t.friction = m.number("friction", 0.8, 0.01, 2.0);
    t.height_m = m.number("height_m", 0.0, -1e4, 1e4);
  } else {
    const auto heightmap = m.required("heightmap");
    t.heightmap = terrain::parse_heightmap_spec(heightmap,
                                                fs::path(node.file()).parent_path().string());
    const std::string image = files.read(t.heightmap.image_file, heightmap.path() + ".image");
    t.heightmap.image_hash = fnv1a64(image);
    // Every process that builds the terrain decodes the whole image: bound it from the PNG
    // header (other formats are checked when decoded).
    const auto png = png_size(image);
    if (png && static_cast<double>(png->first) * png->second > kMaxHeightmapPixels) {
      std::ostringstream msg;
      msg << t.heightmap.image_file << " is " << png->first << " x " << png->second
          << " pixels; at most " << kMaxHeightmapPixels << " (docs/scenario.md, Budgets)";
      MapReader(heightmap).required("image").fail(msg.str());
    }
    t.friction = t.heightmap.friction;
  }
  m.finish();
  return t;
}

world::Obstacle parse_obstacle(const YamlNode& node, const WorldConfig& world) {
  MapReader m(node);
  world::Obstacle o;
  auto id = m.required("id");
  o.id = id.as_string();
  if (!std::regex_match(o.id, std::regex("[A-Za-z0-9_.-]{1,64}"))) {
    id.fail("obstacle id must be 1-64 characters of [A-Za-z0-9_.-], got '" + o.id + "'");
  }
  o.label = m.get_or<std::string>("label", "obstacle");
  const std::string shape = m.choice("shape", std::nullopt, {"box", "sphere", "cylinder"});
  auto pos_node = m.required("position");
  const auto pos = pos_node.as_doubles();
  if (pos.size() != 2 && pos.size() != 3) pos_node.fail("expected [x, y] or [x, y, z]");
  check_in_world(pos_node, world, pos[0], pos[1]);
  if (pos.size() == 3 && std::abs(pos[2]) > 1e4) pos_node.fail("z must be in [-1e4, 1e4]");
  const double yaw = m.number("yaw_deg", 0.0, -360, 360);
  if (shape == "box") {
    o.shape = world::ShapeKind::box;
    auto size = m.required("size_m").as_doubles(3);
    for (double v : size) {
      if (!(v > 0) || v > 1000) m.required("size_m").fail("sizes must be in (0, 1000] m");
    }
    o.size = Vec3(size[0], size[1], size[2]) / 2.0;
  } else if (shape == "sphere") {
    o.shape = world::ShapeKind::sphere;
    const double r = m.number("radius_m", std::nullopt, 1e-3, 500);
    o.size = Vec3(r, r, r);
  } else {
    o.shape = world::ShapeKind::cylinder;
    const double r = m.number("radius_m", std::nullopt, 1e-3, 500);
    o.size = Vec3(r, r, m.number("height_m", std::nullopt, 1e-3, 1000) / 2.0);
  }
  m.finish();
  // Without z the obstacle rests on the terrain (resolved once the terrain is known).
  o.pose.position = Vec3(pos[0], pos[1], pos.size() == 3 ? pos[2] : std::nan(""));
  o.pose.orientation = quat_from_yaw(deg_to_rad(yaw));
  return o;
}

control::PidGains parse_pid(const YamlNode& node, control::PidGains g) {
  MapReader m(node);
  g.kp = m.number("kp", g.kp, -1e3, 1e3);
  g.ki = m.number("ki", g.ki, -1e3, 1e3);
  g.kd = m.number("kd", g.kd, -1e3, 1e3);
  m.finish();
  return g;
}

control::SpeedProfile parse_speed(const YamlNode& node) {
  MapReader m(node);
  control::SpeedProfile s;
  const std::string kind = m.choice("profile", "constant", {"constant", "ramp"});
  s.kind = kind == "ramp" ? control::SpeedProfile::Kind::ramp : control::SpeedProfile::Kind::constant;
  s.target_mps = m.number("target_mps", std::nullopt, 0, 100);
  if (s.kind == control::SpeedProfile::Kind::ramp) {
    s.accel_mps2 = m.positive("accel_mps2", s.accel_mps2);  // the paper's leaders: 0.47
    s.start_mps = m.number("start_mps", 0.0, 0, 100);
  }
  m.finish();
  return s;
}

// A learned policy's file: under the config directory (config/policies/...) or next to the
// scenario; read through `files` so that every process of a run drives with the same bytes.
std::string resolve_policy_file(const YamlNode& node, const std::string& config_dir,
                                ConfigFiles& files) {
  const std::string name = node.as_string();
  fs::path file = fs::path(config_dir) / name;
  if (!fs::exists(file)) file = fs::path(node.file()).parent_path() / name;
  if (!fs::exists(file)) {
    node.fail("policy file not found: " + name + " (looked in " + config_dir + " and next to " +
              node.file() + ")");
  }
  files.read(file.string(), node.path());
  // A policy that reads obstacles from its camera names its perception network in its
  // sidecar (<policy>.json, key "perception", a file beside it): read too, so that every
  // process perceives with the same bytes.
  const fs::path sidecar = fs::path(file).replace_extension(".json");
  if (fs::exists(sidecar)) {
    const YAML::Node meta = YamlNode::load_file(sidecar.string()).raw();
    if (meta.IsMap() && meta["perception"] && meta["perception"].IsScalar()) {
      const fs::path perception = file.parent_path() / meta["perception"].as<std::string>();
      if (!fs::exists(perception)) {
        node.fail("policy file " + name + " names perception network " + perception.string() +
                  " in " + sidecar.string() + ", which is not there");
      }
      files.read(perception.string(), node.path() + " (perception)");
    }
  }
  return file.string();
}

ControllerConfig parse_controller(const YamlNode& node, const WorldConfig& world,
                                  const std::string& config_dir, ConfigFiles& files) {
  MapReader m(node);
  ControllerConfig c;
  c.type = m.choice("type", std::nullopt,
                    {"path_follower", "follower", "policy", "external", "none"});
  if (c.follows()) {
    c.trail_of_head = m.choice("trail", std::string("leader"), {"leader", "head"}) == "head";
  }
  if (c.type == "policy") {
    c.convoy.leader = m.required("follow").as_string();
    c.policy_file = resolve_policy_file(m.required("model"), config_dir, files);
    c.policy_period_s = m.number("period_s", c.policy_period_s, 0.001, 10.0);
  }
  if (c.type == "follower") {
    auto& f = c.convoy;
    f.leader = m.required("follow").as_string();
    if (auto n = m.optional("gap")) {
      MapReader g(*n);
      if (auto old = g.optional("standstill_m")) {
        old->fail("standstill_m (centre to centre) is now standstill_bumper_m, the gap between "
                  "the bumpers at rest: for two HMMWVs (4.7 m long) standstill_m 10 is "
                  "standstill_bumper_m 5.3 (docs/convoy.md)");
      }
      f.time_gap_s = g.number("time_s", f.time_gap_s, 0.0, 10.0);
      f.standstill_bumper_m = g.number("standstill_bumper_m", f.standstill_bumper_m, 0.5, 100.0);
      f.own_decel_mps2 = g.number("own_decel_mps2", f.own_decel_mps2, 0.5, 10.0);
      f.anticipation_s = g.number("anticipation_s", f.anticipation_s, 0.0, 5.0);
      g.finish();
    }
    if (auto old = m.optional("lookahead")) {
      old->fail("the follower no longer steers towards a look-ahead point (it cut the bends): "
                "remove lookahead; the trail tracking's gains are under tracking "
                "(docs/convoy.md)");
    }
    if (auto n = m.optional("tracking")) {
      MapReader t(*n);
      f.heading_gain = t.number("heading_gain", f.heading_gain, 0.0, 10.0);
      f.cross_track_gain_per_s =
          t.number("cross_track_gain_per_s", f.cross_track_gain_per_s, 0.0, 20.0);
      f.understeer_rad_per_mps2 =
          t.number("understeer_rad_per_mps2", f.understeer_rad_per_mps2, -0.1, 0.1);
      t.finish();
    }
    f.max_speed_mps = m.number("max_speed_mps", f.max_speed_mps, 0.1, 100.0);
    f.gap_gain_per_s = m.number("gap_gain_per_s", f.gap_gain_per_s, 0.0, 10.0);
    if (auto n = m.optional("speed_pid")) f.speed_pid = parse_pid(*n, f.speed_pid);
    f.fix_gain = m.number("gps_gain", f.fix_gain, 0.0, 1.0);
    f.leader_fix_gain = m.number("v2v_gain", f.leader_fix_gain, 0.0, 1.0);
    f.leader_lost_after_s = m.number("leader_lost_after_s", f.leader_lost_after_s, 0.05, 600.0);
    if (auto n = m.optional("radar")) {
      MapReader r(*n);
      f.radar_sensor = r.get<std::string>("sensor");
      f.radar_lane_half_width_m =
          r.number("lane_half_width_m", f.radar_lane_half_width_m, 0.1, 10.0);
      f.radar_gate_m = r.number("gate_m", f.radar_gate_m, 0.1, 100.0);
      f.radar_max_age_s = r.number("max_age_s", f.radar_max_age_s, 0.0, 10.0);
      r.finish();
    }
  }
  if (c.type == "path_follower") {
    MapReader p(m.required("path"));
    auto wp = p.required("waypoints");
    if (wp.size() > 100000) wp.fail("at most 100000 waypoints");
    for (const auto& row : wp.elements()) {
      const auto v = row.as_doubles(2);
      check_in_world(row, world, v[0], v[1]);
      c.waypoints.emplace_back(v[0], v[1]);
    }
    if (c.waypoints.size() < 2) wp.fail("needs at least two [x, y] waypoints");
    c.closed = p.get_or("closed", false);
    p.finish();
    try {
      control::Path check(c.waypoints, c.closed);
    } catch (const std::exception& e) {
      wp.fail(e.what());
    }
    c.follower.speed_profile = parse_speed(m.required("speed"));
    c.follower.lookahead_m = m.number("lookahead_m", 5.0, 0.1, 100);
    if (auto n = m.optional("steering_pid")) c.follower.steering = parse_pid(*n, c.follower.steering);
    if (auto n = m.optional("speed_pid")) c.follower.speed = parse_pid(*n, c.follower.speed);
    if (m.has("stop_at_s")) c.stop_at_s = m.number("stop_at_s", std::nullopt, 0.0, kMaxEndTimeS);
  }
  m.finish();
  return c;
}

Pose parse_start(const YamlNode& node, const WorldConfig& world) {
  MapReader m(node);
  Pose p;
  const double x = m.get<double>("x");
  const double y = m.get<double>("y");
  check_in_world(node, world, x, y);
  const double z = m.number("z", 0.0, -1e4, 1e4);
  const double yaw = m.number("yaw_deg", 0.0, -360, 360);
  m.finish();
  p.position = Vec3(x, y, z);
  p.orientation = quat_from_yaw(deg_to_rad(yaw));
  return p;
}

std::string resolve_model_file(const YamlNode& node, const std::string& model,
                               const std::string& config_dir) {
  fs::path file;
  if (model.find('/') != std::string::npos || model.ends_with(".yaml")) {
    file = fs::path(node.file()).parent_path() / model;
  } else {
    file = fs::path(config_dir) / "vehicles" / (model + ".yaml");
  }
  if (!fs::exists(file)) node.fail("vehicle model file not found: " + file.string());
  return file.string();
}

// The meshes a vehicle's renderer will draw (its rig's mesh directory: vehicle_body and every
// obstacle label) are part of the fingerprint, present or absent: a host with another mesh, or
// none, would render another world. The renderer checks the bytes again when it loads them.
void fingerprint_meshes(Scenario& s, ConfigFiles& files) {
  std::set<std::string> names = {"vehicle_body"};
  for (const auto& o : s.obstacles) {
    if (!o.label.empty()) names.insert(o.label);
  }
  for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
    auto& v = s.vehicles[i];
    if (!v.has_rendered_sensors()) continue;
    auto& scene = v.sensors->rig.scene;
    if (scene.mesh_dir.empty()) continue;
    const std::string role = "vehicles[" + std::to_string(i) + "].sensors.meshes.";
    const fs::path materials = fs::path(scene.mesh_dir) / "meshes.mtl";
    if (fs::is_regular_file(materials)) files.read(materials.string(), role + "meshes.mtl");
    for (const auto& name : names) {
      const fs::path file = fs::path(scene.mesh_dir) / (name + ".obj");
      if (fs::is_regular_file(file)) {
        scene.mesh_hashes[name] = fnv1a64(files.read(file.string(), role + name + ".obj"));
      } else {
        files.add(file.string(), role + name + ".obj (absent)", "");
        scene.mesh_hashes[name] = 0;
      }
    }
  }
}

// `sensors: default` (a rig name or file) or `sensors: {rig: default, save_images: true, video: false}`.
VehicleSensorsConfig parse_vehicle_sensors(const YamlNode& node, const std::string& config_dir,
                                           const TimeConfig& time, ConfigFiles& files) {
  const double heartbeat_s = time.heartbeat_s;
  VehicleSensorsConfig c;
  std::optional<YamlNode> rig_node;
  if (node.is_scalar()) {
    rig_node = node;
  } else {
    MapReader m(node);
    rig_node = m.required("rig");
    c.save_images = m.get_or("save_images", false);
    c.video = m.get_or("video", false);
    c.late_join = m.get_or("late_join", false);
    m.finish();
  }
  const std::string rig = rig_node->as_string();
  std::string file = sensors::sensor_rig_path(rig, config_dir);
  if (!fs::exists(file)) file = (fs::path(node.file()).parent_path() / rig).string();
  if (!fs::exists(file)) rig_node->fail("sensor rig not found: " + rig);
  c.rig = sensors::parse_sensor_rig(
      YamlNode::load_string(files.read(file, rig_node->path()), file));
  // The DDS history keeps 32 samples per sensor type, vehicle and frame (two frames in flight).
  auto per_frame = [&](const auto& list) {
    double n = 0;
    for (const auto& sensor : list) n += std::ceil(sensor.rate_hz * heartbeat_s - 1e-9);
    return n;
  };
  for (const auto& [kind, n] : {std::pair{"gps", per_frame(c.rig.gps)},
                                std::pair{"imu", per_frame(c.rig.imus)},
                                std::pair{"magnetometer", per_frame(c.rig.magnetometers)},
                                std::pair{"tachometer", per_frame(c.rig.tachometers)}}) {
    if (n > 32) {
      rig_node->fail(std::string("rig ") + file + ": its " + kind + " sensors make " +
                     std::to_string(static_cast<int>(n)) +
                     " samples per frame; at most 32 fit (lower rate_hz or heartbeat_s)");
    }
  }
  // Cameras, lidars and radars publish one image or scan per frame at most each; a frame's
  // samples of one kind and vehicle must fit the writer's history (TopicTraits::max_per_frame).
  for (const auto& [kind, n, limit] :
       {std::tuple{"camera", per_frame(c.rig.cameras),
                   proto::TopicTraits<proto::Topic::image>::max_per_frame},
        std::tuple{"lidar", per_frame(c.rig.lidars),
                   proto::TopicTraits<proto::Topic::point_cloud>::max_per_frame},
        std::tuple{"radar", per_frame(c.rig.radars),
                   proto::TopicTraits<proto::Topic::radar>::max_per_frame}}) {
    if (n > limit) {
      rig_node->fail(std::string("rig ") + file + ": its " + kind + " sensors make " +
                     std::to_string(static_cast<int>(n)) + " samples per frame; at most " +
                     std::to_string(limit) + " fit (fewer sensors, lower rate_hz or heartbeat_s)");
    }
  }
  // A sensor measures on the grid it is fed at: the dynamics step for the interoceptive ones,
  // the frame for cameras, lidars and radars. Checked here so that a rig too fast for the
  // scenario is refused before any process starts (VehicleSensors checks again with the exact
  // tick rule; the margin here only ever accepts more).
  auto check_rate = [&](const std::string& id, double rate_hz, double tick_s, const char* fed) {
    if (rate_hz * tick_s > 1.0 + 1e-6) {
      std::ostringstream msg;
      msg << "rig " << file << ": sensor '" << id << "' measures at " << rate_hz
          << " Hz, faster than the " << 1.0 / tick_s << " Hz it is fed at (" << fed << ")";
      rig_node->fail(msg.str());
    }
  };
  for (const auto& s : c.rig.gps) check_rate(s.id, s.rate_hz, time.step_s, "time.step_s");
  for (const auto& s : c.rig.imus) check_rate(s.id, s.rate_hz, time.step_s, "time.step_s");
  for (const auto& s : c.rig.magnetometers) check_rate(s.id, s.rate_hz, time.step_s, "time.step_s");
  for (const auto& s : c.rig.tachometers) check_rate(s.id, s.rate_hz, time.step_s, "time.step_s");
  for (const auto& s : c.rig.cameras) check_rate(s.id, s.rate_hz, heartbeat_s, "time.heartbeat_s");
  for (const auto& s : c.rig.lidars) check_rate(s.id, s.rate_hz, heartbeat_s, "time.heartbeat_s");
  for (const auto& s : c.rig.radars) check_rate(s.id, s.rate_hz, heartbeat_s, "time.heartbeat_s");
  return c;
}

VehicleConfig parse_vehicle(const YamlNode& node, const std::string& config_dir,
                            const TimeConfig& time, const WorldConfig& world, ConfigFiles& files) {
  const double heartbeat_s = time.heartbeat_s;
  MapReader m(node);
  VehicleConfig v;
  auto id_node = m.required("id");
  v.id = id_node.as_string();
  if (!std::regex_match(v.id, std::regex("[A-Za-z0-9_-]{1,32}"))) {
    id_node.fail("vehicle id must be 1-32 characters of [A-Za-z0-9_-], got '" + v.id + "'");
  }
  auto model_node = m.required("model");
  v.model = model_node.as_string();
  const std::string model_file = resolve_model_file(model_node, v.model, config_dir);
  v.params = vehicle::parse_vehicle_params(
      YamlNode::load_string(files.read(model_file, model_node.path()), model_file));
  v.dynamics = m.choice("dynamics", "reduced", {"reduced", "full"});
  auto start = m.optional("start");
  if (auto n = m.optional("sensors")) {
    v.sensors = parse_vehicle_sensors(*n, config_dir, time, files);
  }
  std::optional<YamlNode> controller_node = m.optional("controller");
  if (controller_node) {
    v.controller = parse_controller(*controller_node, world, config_dir, files);
    if (v.controller.type == "policy" && v.controller.policy_period_s > 0.0) {
      if (!whole_frames(v.controller.policy_period_s, time.heartbeat_s)) {
        std::ostringstream msg;
        msg << "period_s (" << v.controller.policy_period_s
            << " s) must be a whole multiple of time.heartbeat_s (" << time.heartbeat_s << " s)";
        controller_node->fail(msg.str());
      }
    }
  } else {
    v.controller.type = "none";
  }
  std::optional<YamlNode> v2v_node = m.optional("v2v");
  if (v2v_node) {
    MapReader r(*v2v_node);
    convoy::V2VConfig c;
    c.rate_hz = r.number("rate_hz", c.rate_hz, 0.01, 1.0 / heartbeat_s);
    c.latency_s = r.number("latency_s", c.latency_s, 0.0, 60.0);
    c.drop_probability = r.number("drop_probability", c.drop_probability, 0.0, 1.0);
    r.finish();
    v.v2v = c;
  }
  // V2V and the follower work from the vehicle's own GPS, compass and tachometer.
  auto needs_own_sensors = [&](const YamlNode& where, const char* what) {
    const auto* rig = v.sensors ? &v.sensors->rig : nullptr;
    if (!rig || rig->gps.empty() || rig->magnetometers.empty() || rig->tachometers.empty()) {
      where.fail(std::string(what) + " needs the vehicle's own GPS, magnetometer and tachometer: "
                "give the vehicle a sensor rig with all three (e.g. sensors: convoy)");
    }
  };
  if (v2v_node) needs_own_sensors(*v2v_node, "v2v");
  if (v.controller.follows()) {
    needs_own_sensors(*controller_node, ("a " + v.controller.type + " controller").c_str());
  }
  if (const std::string& radar = v.controller.convoy.radar_sensor; !radar.empty()) {
    const auto& radars = v.sensors->rig.radars;
    if (std::none_of(radars.begin(), radars.end(), [&](const auto& r) { return r.id == radar; })) {
      MapReader(*controller_node).required("radar").fail(
          "no radar '" + radar + "' in the vehicle's sensor rig " + v.sensors->rig.file);
    }
  }
  if (start) {
    v.start = parse_start(*start, world);
  } else if (v.controller.type == "path_follower") {
    const control::Path path(v.controller.waypoints, v.controller.closed);
    const auto p0 = path.at(0.0);
    v.start.position = Vec3(p0.position.x(), p0.position.y(), 0.0);
    v.start.orientation = quat_from_yaw(std::atan2(p0.tangent.y(), p0.tangent.x()));
  } else {
    m.required("start");  // throws: needed when there is no path to start from
  }
  m.finish();
  return v;
}

}  // namespace

std::int64_t TimeConfig::steps_per_frame() const {
  return static_cast<std::int64_t>(std::llround(heartbeat_s / step_s));
}

std::int64_t TimeConfig::final_frame() const {
  return static_cast<std::int64_t>(std::ceil(end_time_s / heartbeat_s - 1e-9));
}

const VehicleConfig* Scenario::find_vehicle(const std::string& id) const {
  for (const auto& v : vehicles) {
    if (v.id == id) return &v;
  }
  return nullptr;
}

bool VehicleConfig::has_interoceptive_sensors() const {
  if (!sensors) return false;
  const auto& r = sensors->rig;
  return !r.gps.empty() || !r.imus.empty() || !r.magnetometers.empty() || !r.tachometers.empty();
}

std::vector<std::string> Scenario::member_ids() const {
  std::vector<std::string> out;
  for (const auto& v : vehicles) out.push_back(vehicle_member(v.id));
  for (const auto& v : vehicles) {
    if (v.controller.is_builtin()) out.push_back(controller_member(v.id));
    if (v.controller.type == "external") out.push_back(external_member(v.id));
  }
  for (const auto& v : vehicles) {
    if (v.has_rendered_sensors()) out.push_back(sensor_member(v.id));
  }
  if (recorder.enabled) out.push_back(kRecorderMember);
  return out;
}

bool Scenario::is_late_member(const std::string& member_id) const {
  for (const auto& v : vehicles) {
    if (member_id == sensor_member(v.id) && v.has_rendered_sensors() && v.sensors->late_join) {
      return true;
    }
  }
  return false;
}

std::optional<ProcessLayout> ProcessLayout::parse(const std::string& text) {
  ProcessLayout l;
  if (text == "per_member") return l;
  if (text == "per_vehicle") {
    l.kind = Kind::per_vehicle;
    return l;
  }
  if (!text.empty() && text.size() <= 3 &&
      text.find_first_not_of("0123456789") == std::string::npos && std::stoi(text) >= 1) {
    l.kind = Kind::groups;
    l.groups = std::stoi(text);
    return l;
  }
  return std::nullopt;
}

std::string ProcessLayout::to_string() const {
  switch (kind) {
    case Kind::per_member: return "per_member";
    case Kind::per_vehicle: return "per_vehicle";
    case Kind::groups: break;
  }
  return std::to_string(groups);
}

std::vector<std::vector<std::string>> Scenario::process_members(
    const ProcessLayout& layout) const {
  using Kind = ProcessLayout::Kind;
  std::vector<std::vector<std::string>> out;
  if (layout.kind == Kind::per_member) {
    for (const auto& m : member_ids()) {
      if (m.rfind("external/", 0) != 0) out.push_back({m});
    }
    return out;
  }
  // A vehicle's own members; late-joining sensors keep a process of their own (started later).
  std::vector<std::string> late;
  auto members_of = [&](const VehicleConfig& v) {
    std::vector<std::string> m = {vehicle_member(v.id)};
    if (v.controller.is_builtin()) m.push_back(controller_member(v.id));
    if (v.has_rendered_sensors()) {
      (is_late_member(sensor_member(v.id)) ? late : m).push_back(sensor_member(v.id));
    }
    return m;
  };
  const std::size_t n = vehicles.size();
  const std::size_t groups =
      layout.kind == Kind::per_vehicle ? n : std::min(n, static_cast<std::size_t>(layout.groups));
  // Vehicles in scenario order, split into `groups` runs of consecutive vehicles whose sizes
  // differ by at most one.
  for (std::size_t g = 0, next = 0; g < groups; ++g) {
    const std::size_t count = n / groups + (g < n % groups ? 1 : 0);
    std::vector<std::string> members;
    for (std::size_t i = 0; i < count; ++i, ++next) {
      const auto m = members_of(vehicles[next]);
      members.insert(members.end(), m.begin(), m.end());
    }
    out.push_back(std::move(members));
  }
  for (const auto& m : late) out.push_back({m});
  if (recorder.enabled) out.push_back({kRecorderMember});
  return out;
}

std::string vehicle_member(const std::string& id) { return "vehicle/" + id; }
std::string controller_member(const std::string& id) { return "controller/" + id; }
std::string external_member(const std::string& id) { return "external/" + id; }
std::string sensor_member(const std::string& id) { return "sensor/" + id; }

std::string default_config_dir() {
  if (const char* env = std::getenv("SYNDDS_CONFIG_DIR"); env && *env) return env;
  return SYNDDS_DEFAULT_CONFIG_DIR;
}

Scenario parse_scenario_config(const YamlNode& root, const std::string& text,
                               const Overrides& overrides, const std::string& config_dir) {
  Scenario s;
  s.file = root.file();
  ConfigFiles files;
  files.add(s.file, "scenario", text);
  MapReader m(root);
  s.name = m.get_or<std::string>("name", fs::path(s.file).stem().string());
  s.seed = static_cast<std::uint64_t>(m.number("seed", 1, 0, 9.0e15));
  s.time = parse_time(m.required("time"));
  if (auto n = m.optional("coordinator")) s.coordinator = parse_coordinator(*n);
  if (auto n = m.optional("dds")) s.dds = parse_dds(*n);
  if (auto n = m.optional("world")) s.world = parse_world(*n);
  if (auto n = m.optional("terrain")) s.terrain = parse_terrain(*n, config_dir, files);
  if (auto n = m.optional("obstacles")) {
    if (n->size() > 10000) n->fail("at most 10000 obstacles");
    std::set<std::string> obstacle_ids;
    for (const auto& o : n->elements()) {
      s.obstacles.push_back(parse_obstacle(o, s.world));
      if (!obstacle_ids.insert(s.obstacles.back().id).second) {
        o.fail("duplicate obstacle id '" + s.obstacles.back().id + "'");
      }
    }
  }
  auto vehicles = m.required("vehicles");
  // Checked before any vehicle file is read: each vehicle is at least one process to start.
  if (vehicles.size() > kMaxVehicles) {
    vehicles.fail(std::to_string(vehicles.size()) + " vehicles; at most " +
                  std::to_string(kMaxVehicles) + " in one run (docs/scenario.md, Budgets)");
  }
  std::set<std::string> ids;
  for (const auto& v : vehicles.elements()) {
    s.vehicles.push_back(parse_vehicle(v, config_dir, s.time, s.world, files));
    if (!ids.insert(s.vehicles.back().id).second) {
      v.fail("duplicate vehicle id '" + s.vehicles.back().id + "'");
    }
  }
  if (s.vehicles.empty()) vehicles.fail("needs at least one vehicle");
  fingerprint_meshes(s, files);
  // A follower follows another vehicle of this scenario, one that broadcasts V2V.
  {
    const auto nodes = vehicles.elements();
    for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
      const auto& v = s.vehicles[i];
      if (!v.controller.follows()) continue;
      const std::string& leader = v.controller.convoy.leader;
      const VehicleConfig* l = s.find_vehicle(leader);
      if (!l || leader == v.id) {
        nodes[i].fail("controller.follow: '" + leader + "' is not another vehicle of this scenario");
      }
      if (!l->v2v) {
        nodes[i].fail("controller.follow: vehicle '" + leader +
                      "' sends no V2V messages (give it a v2v: block)");
      }
    }
    // Every follow chain ends at a vehicle that follows nobody (its convoy's leader: the
    // deviation metrics are measured against it, and `trail: head` steers along its trail).
    for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
      std::set<std::string> seen = {s.vehicles[i].id};
      std::string chain = s.vehicles[i].id;
      const VehicleConfig* v = &s.vehicles[i];
      while (v->controller.follows()) {
        v = s.find_vehicle(v->controller.convoy.leader);
        chain += " -> " + v->id;
        if (!seen.insert(v->id).second) {
          nodes[i].fail("controller.follow: follow chain without a leader: " + chain);
        }
      }
      auto& c = s.vehicles[i].controller;
      if (c.trail_of_head) c.convoy.trail_of = v->id;
    }
  }
  if (auto n = m.optional("processes")) {
    const auto layout = ProcessLayout::parse(n->as_string());
    if (!layout) n->fail("'" + n->as_string() + "': " + ProcessLayout::kExpected);
    s.processes = *layout;
  }
  if (auto n = m.optional("recorder")) {
    MapReader r(*n);
    s.recorder.enabled = r.get_or("enabled", true);
    if (auto skip = r.optional("skip")) {
      if (!skip->is_sequence()) skip->fail("expected a list of file names, e.g. [commands, wheels]");
      for (const auto& e : skip->elements()) {
        const std::string name = e.as_string();
        const auto& known = kSkippableFiles;
        if (std::find(std::begin(known), std::end(known), name) == std::end(known)) {
          std::string list;
          for (const char* k : known) list += std::string(list.empty() ? "" : ", ") + k;
          e.fail("'" + name + "' is not a file the recorder may skip (" + list +
                 "; vehicles and events are always written)");
        }
        if (!s.recorder.skip.insert(name).second) e.fail("'" + name + "' is listed twice");
      }
    }
    if (!s.recorder.enabled && s.terrain.deformable() && s.terrain.scm.routing) {
      r.required("enabled").fail(
          "the recorder keeps the whole soil that terrain.scm.routing sends to vehicles as they "
          "come near: it cannot be disabled with routing");
    }
    r.finish();
  }
  if (auto n = m.optional("checkpoint")) {
    MapReader r(*n);
    const auto every = r.required("every_s");
    s.checkpoint.every_s = r.number("every_s", 0.0, 0.0, kMaxEndTimeS);
    const double frames = s.checkpoint.every_s / s.time.heartbeat_s;
    if (s.checkpoint.every_s > 0.0 &&
        (frames < 1.0 || std::abs(frames - std::round(frames)) > 1e-9 * frames)) {
      std::ostringstream msg;
      msg << "every_s (" << s.checkpoint.every_s << ") must be a whole multiple of heartbeat_s ("
          << s.time.heartbeat_s << ")";
      every.fail(msg.str());
    }
    s.checkpoint.every_frames = static_cast<std::int64_t>(std::llround(frames));
    if (auto keep = r.optional("keep_last")) {
      s.checkpoint.keep_last = keep->as_int();
      if (s.checkpoint.keep_last < 1) {
        keep->fail(
            "must be at least 1 (the newest complete checkpoint is what a resume or a "
            "recovery starts from), got " +
            std::to_string(s.checkpoint.keep_last));
      }
    }
    r.finish();
  }
  if (s.coordinator.on_member_loss == proto::LossPolicy::recover) {
    // A lost member is recovered by rolling every member back to a checkpoint.
    const YamlNode policy = MapReader(m.required("coordinator")).required("on_member_loss");
    if (!s.checkpoint.enabled()) {
      policy.fail("recover rolls the run back to its last checkpoint: set checkpoint: every_s");
    }
    // External controllers take part as well: the user's program keeps its own checkpoints
    // and rolls back with the rest (docs/protocol.md, "External controllers").
  }
  m.finish();
  if (const auto members = s.member_ids().size(); members > kMaxMembers) {
    vehicles.fail("these vehicles make " + std::to_string(members) +
                  " processes (vehicles, controllers, sensors, recorder); at most " +
                  std::to_string(kMaxMembers) + " in one run (docs/scenario.md, Budgets)");
  }

  if (overrides.duration_s) {
    const double d = *overrides.duration_s;
    if (!(d > 0.0) || !(d <= kMaxEndTimeS)) {
      std::ostringstream msg;
      msg << "--duration " << d << ": must be in (0, " << kMaxEndTimeS << "] seconds";
      throw ConfigError(msg.str());
    }
    s.time.end_time_s = d;
  }
  if (overrides.realtime) s.time.realtime = *overrides.realtime;
  if (overrides.domain_id) s.dds.domain_id = *overrides.domain_id;

  s.files = files.files();
  Fnv1a64 h;
  h.add(static_cast<std::int64_t>(files.fingerprint()));
  h.add(s.time.end_time_s);
  h.add(static_cast<std::int64_t>(s.time.realtime));
  s.fingerprint = h.value();
  return s;
}

Scenario load_scenario_config(const std::string& file, const Overrides& overrides,
                              const std::string& config_dir) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw ConfigError(file + ": cannot open scenario file");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  return parse_scenario_config(YamlNode::load_string(text, file), text, overrides, config_dir);
}

std::optional<std::int64_t> whole_frames(double period_s, double heartbeat_s) {
  const double frames = period_s / heartbeat_s;
  if (frames < 1.0 - 1e-9 || std::abs(frames - std::round(frames)) > 1e-6) return std::nullopt;
  return std::llround(frames);
}

}  // namespace syndds::scenario
