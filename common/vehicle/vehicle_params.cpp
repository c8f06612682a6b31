#include "vehicle/vehicle_params.hpp"

#include <algorithm>
#include <cmath>

namespace syndds::vehicle {
namespace {

constexpr double kBig = 1e12;

Vec3 vec3(MapReader& m, std::string_view key, std::optional<Vec3> fallback = std::nullopt) {
  auto n = m.optional(key);
  if (!n) {
    if (!fallback) m.required(key);  // throws "missing required key"
    return *fallback;
  }
  const auto v = n->as_doubles(3);
  return Vec3(v[0], v[1], v[2]);
}

AxleParams parse_axle(const YamlNode& node, bool steered_default) {
  MapReader m(node);
  AxleParams a;
  a.x_m = m.number("x_m", std::nullopt, -20, 20);
  a.half_track_m = m.positive("half_track_m", std::nullopt);
  a.spring_rate_npm = m.positive("spring_rate_npm", std::nullopt);
  a.damping_nspm = m.positive("damping_nspm", std::nullopt);
  a.travel_m = m.positive("travel_m", std::nullopt);
  a.preload_n = m.number("preload_n", -1.0, -1.0, kBig);
  a.bump_stop_rate_npm = m.number("bump_stop_rate_npm", 0.0, 0.0, kBig);
  a.steered = m.get_or("steered", steered_default);
  a.driven = m.get_or("driven", true);
  a.brake_torque_nm = m.number("brake_torque_nm", std::nullopt, 0, kBig);
  m.finish();
  return a;
}

/// Linear interpolation in rows sorted by x, clamped at the ends.
double interpolate(const std::vector<std::pair<double, double>>& map, double x) {
  if (map.empty()) return 0.0;
  if (x <= map.front().first) return map.front().second;
  if (x >= map.back().first) return map.back().second;
  auto hi = std::lower_bound(map.begin(), map.end(), x,
                             [](const auto& p, double v) { return p.first < v; });
  auto lo = hi - 1;
  const double t = (x - lo->first) / (hi->first - lo->first);
  return lo->second + t * (hi->second - lo->second);
}

/// Rows [x, y] with x strictly increasing; `what` names the columns in errors.
std::vector<std::pair<double, double>> parse_rows(const YamlNode& node, const char* what) {
  std::vector<std::pair<double, double>> rows;
  for (const auto& row : node.elements()) {
    const auto v = row.as_doubles(2);
    if (!rows.empty() && v[0] <= rows.back().first) {
      row.fail(std::string("the first column (") + what + ") must increase");
    }
    rows.emplace_back(v[0], v[1]);
  }
  if (rows.size() < 2) node.fail(std::string("needs at least two [") + what + "] rows");
  return rows;
}

/// A converter map over the speed ratio: from sr 0 to sr 1, values positive.
ConverterMap parse_converter_map(MapReader& m, std::string_view key, const char* what) {
  const YamlNode node = m.required(key);
  ConverterMap rows = parse_rows(node, what);
  if (rows.front().first != 0.0 || rows.back().first != 1.0) {
    node.fail("speed ratios must run from 0 to 1 (first row sr 0, last row sr 1)");
  }
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (!(rows[i].second > 0.0)) node[i].fail("value must be positive");
  }
  return rows;
}

}  // namespace

double VehicleParams::engine_torque_nm(double rpm) const {
  return interpolate(engine.torque_map_rpm_nm, rpm);
}

double VehicleParams::converter_capacity(double speed_ratio) const {
  return interpolate(transmission.converter_capacity_map, clamp(speed_ratio, 0.0, 1.0));
}

double VehicleParams::converter_torque_ratio(double speed_ratio) const {
  return interpolate(transmission.converter_torque_ratio_map, clamp(speed_ratio, 0.0, 1.0));
}

double VehicleParams::driveline_inertia_at_wheels_kgm2(int gear) const {
  const double final_drive = driveline.final_drive_ratio;
  double j = driveline.driveshaft_inertia_kgm2 / (final_drive * final_drive);
  if (gear >= 1 && gear <= static_cast<int>(transmission.forward_ratios.size())) {
    const double overall = transmission.forward_ratios[static_cast<std::size_t>(gear - 1)] *
                           final_drive;
    j += transmission.ingear_shaft_inertia_kgm2 / (overall * overall);
  }
  return j;
}

std::pair<double, double> VehicleParams::engine_peak_torque() const {
  std::pair<double, double> best{0.0, 0.0};  // (torque, rpm)
  for (const auto& [rpm, torque] : engine.torque_map_rpm_nm) {
    if (torque > best.first) best = {torque, rpm};
  }
  return best;
}

double VehicleParams::total_com_x_m() const {
  const double wheels_x = 2.0 * wheels.mass_kg * (front.x_m + rear.x_m);
  return (chassis.mass_kg * chassis.com_m.x() + wheels_x) / total_mass_kg();
}

double VehicleParams::static_wheel_load_n(bool front_axle) const {
  const double x = total_com_x_m();
  const double share = front_axle ? (x - rear.x_m) / wheelbase_m()   // b / L
                                  : (front.x_m - x) / wheelbase_m();  // a / L
  return total_mass_kg() * kGravity * share / 2.0;
}

double VehicleParams::engine_motoring_torque_nm() const {
  if (engine.motoring_torque_nm >= 0) return engine.motoring_torque_nm;
  return 0.1 * engine_peak_torque().first;
}

VehicleParams parse_vehicle_params(const YamlNode& root) {
  VehicleParams p;
  p.source_file = root.file();
  MapReader top(root);
  p.name = top.get<std::string>("name");

  {
    MapReader m(top.required("chassis"));
    p.chassis.mass_kg = m.positive("mass_kg", std::nullopt);
    p.chassis.inertia_kgm2 = vec3(m, "inertia_kgm2");
    p.chassis.com_m = vec3(m, "com_m");
    p.chassis.half_extents_m = vec3(m, "half_extents_m", p.chassis.half_extents_m);
    p.chassis.box_centre_m = vec3(m, "box_centre_m", p.chassis.box_centre_m);
    p.chassis.drag_area_m2 = m.number("drag_area_m2", 0.0, 0, 100);
    m.finish();
    if ((p.chassis.inertia_kgm2.array() <= 0).any()) {
      top.required("chassis").fail("inertia_kgm2 must be positive");
    }
  }
  {
    MapReader m(top.required("wheels"));
    p.wheels.radius_m = m.positive("radius_m", std::nullopt);
    p.wheels.width_m = m.positive("width_m", std::nullopt);
    p.wheels.mass_kg = m.positive("mass_kg", std::nullopt);
    p.wheels.spin_inertia_kgm2 = m.positive("spin_inertia_kgm2", std::nullopt);
    m.finish();
  }
  p.front = parse_axle(top.required("front_axle"), true);
  p.rear = parse_axle(top.required("rear_axle"), false);
  if (p.wheelbase_m() <= 0) top.required("rear_axle").fail("x_m must be behind front_axle.x_m");
  if (p.rear.steered) {
    top.required("rear_axle").fail("steered: rear-axle steering is not supported");
  }
  if (!p.front.driven && !p.rear.driven) {
    top.required("rear_axle").fail("driven: at least one axle must be driven");
  }
  {
    MapReader m(top.required("steering"));
    p.steering.max_angle_deg = m.number("max_angle_deg", std::nullopt, 1, 60);
    p.steering.rate_deg_s = m.number("rate_deg_s", 0.0, 0, kBig);
    m.finish();
  }
  {
    MapReader m(top.required("engine"));
    p.engine.torque_map_rpm_nm = parse_rows(m.required("torque_map_rpm_nm"), "rpm, Nm");
    p.engine.idle_rpm = m.positive("idle_rpm", std::nullopt);
    p.engine.max_rpm = m.positive("max_rpm", std::nullopt);
    p.engine.inertia_kgm2 = m.positive("inertia_kgm2", std::nullopt);
    p.engine.motoring_torque_nm = m.number("motoring_torque_nm", -1.0, -1.0, kBig);
    m.finish();
    if (p.engine.idle_rpm >= p.engine.max_rpm) {
      top.required("engine").fail("idle_rpm must be below max_rpm");
    }
    if (p.engine_peak_torque().first <= 0) {
      top.required("engine").fail("torque_map_rpm_nm needs a positive torque");
    }
  }
  {
    MapReader m(top.required("transmission"));
    auto ratios = m.required("forward_ratios");
    p.transmission.forward_ratios = ratios.as_doubles();
    if (p.transmission.forward_ratios.empty()) ratios.fail("needs at least one gear");
    for (std::size_t i = 0; i < p.transmission.forward_ratios.size(); ++i) {
      if (p.transmission.forward_ratios[i] <= 0) ratios[i].fail("gear ratio must be positive");
    }
    p.transmission.reverse_ratio = m.number("reverse_ratio", std::nullopt, -10, 0);
    p.transmission.upshift_rpm = m.positive("upshift_rpm", std::nullopt);
    p.transmission.downshift_rpm = m.positive("downshift_rpm", std::nullopt);
    p.transmission.shift_time_s = m.number("shift_time_s", 0.0, 0, 5);
    for (const char* old : {"converter_stall_ratio", "converter_coupling_speed_ratio",
                            "converter_capacity_factor"}) {
      if (auto n = m.optional(old)) {
        n->fail("replaced by converter_capacity_map and converter_torque_ratio_map "
                "(maps over the speed ratio, see docs/vehicle-dynamics.md)");
      }
    }
    p.transmission.converter_capacity_map =
        parse_converter_map(m, "converter_capacity_map", "speed ratio, K rad/s/sqrt(N m)");
    p.transmission.converter_torque_ratio_map =
        parse_converter_map(m, "converter_torque_ratio_map", "speed ratio, torque ratio");
    p.transmission.ingear_shaft_inertia_kgm2 =
        m.number("ingear_shaft_inertia_kgm2", 0.0, 0, kBig);
    m.finish();
    if (p.transmission.downshift_rpm >= p.transmission.upshift_rpm) {
      top.required("transmission").fail("downshift_rpm must be below upshift_rpm");
    }
  }
  {
    MapReader m(top.required("driveline"));
    p.driveline.final_drive_ratio = m.positive("final_drive_ratio", std::nullopt);
    p.driveline.front_torque_share = m.number("front_torque_share", 0.5, 0, 1);
    p.driveline.driveshaft_inertia_kgm2 = m.number("driveshaft_inertia_kgm2", 0.0, 0, kBig);
    p.driveline.axle_differential_bias = m.number("axle_differential_bias", 1.0, 1.0, 100.0);
    p.driveline.centre_differential_bias =
        m.number("centre_differential_bias", 1.0, 1.0, 100.0);
    m.finish();
  }
  {
    MapReader m(top.required("tire"));
    p.tire.friction_scale = m.number("friction_scale", 1.0, 0.01, 3);
    p.tire.longitudinal_stiffness = m.positive("longitudinal_stiffness", std::nullopt);
    p.tire.cornering_stiffness = m.positive("cornering_stiffness", std::nullopt);
    p.tire.nominal_load_n = m.positive("nominal_load_n", std::nullopt);
    p.tire.vertical_stiffness_npm = m.positive("vertical_stiffness_npm", std::nullopt);
    p.tire.vertical_damping_nspm = m.positive("vertical_damping_nspm", std::nullopt);
    p.tire.rolling_resistance = m.number("rolling_resistance", 0.015, 0, 0.5);
    p.tire.relaxation_length_m = m.number("relaxation_length_m", 0.25, 0.01, 5);
    p.tire.stiffness_load_exponent = m.number("stiffness_load_exponent", 0.8, 0, 2);
    m.finish();
  }
  {
    MapReader m(top.required("reduced"));
    p.reduced.max_drive_force_n = m.positive("max_drive_force_n", std::nullopt);
    p.reduced.max_power_w = m.positive("max_power_w", std::nullopt);
    p.reduced.max_brake_decel_mps2 = m.positive("max_brake_decel_mps2", std::nullopt);
    p.reduced.drag_area_m2 = m.number("drag_area_m2", 0.0, 0, 100);
    p.reduced.steering_time_constant_s = m.number("steering_time_constant_s", 0.1, 0, 5);
    p.reduced.max_speed_mps = m.positive("max_speed_mps", std::nullopt);
    m.finish();
  }
  top.finish();
  return p;
}

VehicleParams load_vehicle_params(const std::string& file) {
  return parse_vehicle_params(YamlNode::load_file(file));
}

}  // namespace syndds::vehicle
