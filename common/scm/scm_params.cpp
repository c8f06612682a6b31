#include "scm/scm_params.hpp"

#include <cmath>
#include <sstream>

namespace syndds::scm {
namespace {

constexpr double kBig = 1e15;

void require(bool ok, const std::string& message) {
  if (!ok) throw ConfigError("SCM parameters: " + message);
}

int integer(MapReader& m, std::string_view key, int fallback, int lo, int hi) {
  auto n = m.optional(key);
  if (!n) return fallback;
  const auto v = n->as_int();
  if (v < lo || v > hi) {
    n->fail("must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
            std::to_string(v));
  }
  return static_cast<int>(v);
}

}  // namespace

SoilParams soil_preset(const std::string& name) {
  SoilParams s;
  if (name == "soft") {
    s.bekker_kphi = 0.2e6;
    s.bekker_kc = 0.0;
    s.bekker_n = 1.1;
    s.cohesion_pa = 0.0;
    s.friction_angle_deg = 30.0;
    s.janosi_shear_m = 0.01;
    s.elastic_stiffness_pa_per_m = 4e7;
    s.damping_pa_s_per_m = 3e4;
  } else if (name == "mid") {
    s.bekker_kphi = 2e6;
    s.bekker_kc = 0.0;
    s.bekker_n = 1.1;
    s.cohesion_pa = 0.0;
    s.friction_angle_deg = 30.0;
    s.janosi_shear_m = 0.01;
    s.elastic_stiffness_pa_per_m = 2e8;
    s.damping_pa_s_per_m = 3e4;
  } else if (name == "hard") {
    s.bekker_kphi = 5301e3;
    s.bekker_kc = 102e3;
    s.bekker_n = 0.793;
    s.cohesion_pa = 1.3e3;
    s.friction_angle_deg = 31.1;
    s.janosi_shear_m = 0.012;
    s.elastic_stiffness_pa_per_m = 4e8;
    s.damping_pa_s_per_m = 3e4;
  } else {
    throw ConfigError("unknown SCM soil preset '" + name + "' (known: soft, mid, hard)");
  }
  return s;
}

SoilParams parse_soil_params(const YamlNode& node) {
  MapReader m(node);
  SoilParams s;
  s.bekker_kphi = m.number("bekker_kphi", std::nullopt, 0.0, kBig);
  s.bekker_kc = m.number("bekker_kc", std::nullopt, 0.0, kBig);
  s.bekker_n = m.number("bekker_n", std::nullopt, 0.1, 3.0);
  s.cohesion_pa = m.number("cohesion_pa", std::nullopt, 0.0, kBig);
  s.friction_angle_deg = m.number("friction_angle_deg", std::nullopt, 0.0, 89.0);
  s.janosi_shear_m = m.positive("janosi_shear_m", std::nullopt);
  s.elastic_stiffness_pa_per_m = m.positive("elastic_stiffness_pa_per_m", std::nullopt);
  s.damping_pa_s_per_m = m.number("damping_pa_s_per_m", std::nullopt, 0.0, kBig);
  m.finish();
  if (s.bekker_kphi <= 0.0 && s.bekker_kc <= 0.0) {
    node.fail("bekker_kphi and bekker_kc cannot both be zero");
  }
  return s;
}

BulldozingParams parse_bulldozing_params(const YamlNode& node, const BulldozingParams& defaults) {
  MapReader m(node);
  BulldozingParams b = defaults;
  b.enabled = m.get_or("enabled", defaults.enabled);
  b.erosion_angle_deg = m.number("erosion_angle_deg", defaults.erosion_angle_deg, 1.0, 89.0);
  b.flow_factor = m.number("flow_factor", defaults.flow_factor, 0.0, 10.0);
  b.iterations = integer(m, "iterations", defaults.iterations, 0, 1000);
  b.propagations = integer(m, "propagations", defaults.propagations, 0, 1000);
  m.finish();
  return b;
}

SoilPreset load_soil_preset_file(const std::string& file, ConfigFiles* files,
                                 const std::string& role) {
  const YamlNode root = files ? YamlNode::load_string(files->read(file, role), file)
                              : YamlNode::load_file(file);
  MapReader m(root);
  SoilPreset p;
  p.soil = parse_soil_params(m.required("soil"));
  if (auto b = m.optional("bulldozing")) p.bulldozing = parse_bulldozing_params(*b, {});
  m.finish();
  return p;
}

ScmParams parse_scm_params(const YamlNode& node, const std::string& terrain_config_dir,
                           ConfigFiles* files) {
  MapReader m(node);
  ScmParams p;
  if (m.has("type")) m.choice("type", std::nullopt, {"scm"});  // a scenario's terrain block
  const bool has_preset = m.has("preset");
  const bool has_soil = m.has("soil");
  if (has_preset == has_soil) node.fail("give exactly one of 'preset' or 'soil'");
  if (has_preset) {
    const std::string name = m.choice("preset", std::nullopt, {"soft", "mid", "hard"});
    const SoilPreset preset = load_soil_preset_file(
        terrain_config_dir + "/scm_" + name + ".yaml", files, m.required("preset").path());
    p.soil = preset.soil;
    p.bulldozing = preset.bulldozing;
  } else {
    p.soil = parse_soil_params(m.required("soil"));
  }
  if (auto b = m.optional("bulldozing")) p.bulldozing = parse_bulldozing_params(*b, p.bulldozing);
  p.grid.spacing_m = m.number("spacing_m", std::nullopt, 1e-4, 10.0);
  {
    const YamlNode area_node = m.required("area");
    MapReader a(area_node);
    p.grid.x_min_m = a.number("x_min_m", std::nullopt, -1e6, 1e6);
    p.grid.x_max_m = a.number("x_max_m", std::nullopt, -1e6, 1e6);
    p.grid.y_min_m = a.number("y_min_m", std::nullopt, -1e6, 1e6);
    p.grid.y_max_m = a.number("y_max_m", std::nullopt, -1e6, 1e6);
    a.finish();
    if (!(p.grid.x_max_m > p.grid.x_min_m) || !(p.grid.y_max_m > p.grid.y_min_m)) {
      area_node.fail("area must have x_max_m > x_min_m and y_max_m > y_min_m");
    }
  }
  p.grid.base_height_m = m.number("base_height_m", 0.0, -1e5, 1e5);
  p.threads = integer(m, "threads", 1, 1, 64);
  p.interest_radius_m = m.number("interest_radius_m", p.interest_radius_m, 0.0, 1e4);
  if (p.interest_radius_m > 0.0 && p.interest_radius_m < 5.0) {
    m.required("interest_radius_m")
        .fail("0 (off) or at least 5 m: a vehicle touches the soil up to about 3 m from its "
              "chassis, plus a frame's travel and the bulldozing rim");
  }
  p.routing = m.get_or<bool>("routing", p.routing);
  if (p.routing && p.interest_radius_m == 0.0) {
    m.required("routing").fail("routing needs interest management (interest_radius_m > 0)");
  }
  p.patch_test_height_m = m.number("patch_test_height_m", p.patch_test_height_m, 0.0, 10.0);
  p.shear_damping_time_s = m.number("shear_damping_time_s", p.shear_damping_time_s, 0.0, 1.0);
  m.finish();
  try {
    validate(p);
  } catch (const ConfigError& e) {
    node.fail(e.what());
  }
  return p;
}

void validate(const ScmParams& p) {
  const auto& s = p.soil;
  require(s.bekker_kphi >= 0.0 && s.bekker_kc >= 0.0 && s.bekker_kphi + s.bekker_kc > 0.0,
          "bekker_kphi and bekker_kc must be >= 0 and not both zero");
  require(s.bekker_n > 0.0, "bekker_n must be positive");
  require(s.cohesion_pa >= 0.0, "cohesion_pa must be >= 0");
  require(s.friction_angle_deg >= 0.0 && s.friction_angle_deg < 90.0,
          "friction_angle_deg must be in [0, 90)");
  require(s.janosi_shear_m > 0.0, "janosi_shear_m must be positive");
  require(s.elastic_stiffness_pa_per_m > 0.0, "elastic_stiffness_pa_per_m must be positive");
  require(s.damping_pa_s_per_m >= 0.0, "damping_pa_s_per_m must be >= 0");
  const auto& b = p.bulldozing;
  require(b.erosion_angle_deg > 0.0 && b.erosion_angle_deg < 90.0,
          "erosion_angle_deg must be in (0, 90)");
  require(b.flow_factor >= 0.0, "flow_factor must be >= 0");
  require(b.iterations >= 0 && b.propagations >= 0, "iterations/propagations must be >= 0");
  const auto& g = p.grid;
  require(g.spacing_m > 0.0 && std::isfinite(g.spacing_m), "spacing_m must be positive");
  require(g.x_max_m > g.x_min_m && g.y_max_m > g.y_min_m, "area must not be empty");
  const double nx = std::floor(g.x_max_m / g.spacing_m) - std::ceil(g.x_min_m / g.spacing_m);
  const double ny = std::floor(g.y_max_m / g.spacing_m) - std::ceil(g.y_min_m / g.spacing_m);
  require(std::abs(g.x_min_m / g.spacing_m) < 2e9 && std::abs(g.x_max_m / g.spacing_m) < 2e9 &&
              std::abs(g.y_min_m / g.spacing_m) < 2e9 && std::abs(g.y_max_m / g.spacing_m) < 2e9,
          "area too large for the grid spacing (indices must fit 32 bits)");
  require(nx >= 0 && ny >= 0, "area holds no grid vertex");
  require(p.patch_test_height_m >= 0.0, "patch_test_height_m must be >= 0");
  require(p.shear_damping_time_s >= 0.0 && std::isfinite(p.shear_damping_time_s),
          "shear_damping_time_s must be >= 0");
  require(p.thread_min_vertices >= 1, "thread_min_vertices must be >= 1");
  require(p.threads >= 1 && p.threads <= 64, "threads must be in [1, 64]");
}

}  // namespace syndds::scm
