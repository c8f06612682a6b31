#pragma once
// Vehicle definition files (config/vehicles/*.yaml) read strictly into plain structs.
// One file serves both the full multibody model (ODE) and the reduced-order model.
// Frames: chassis reference frame at the midpoint between the axles at wheel-centre height,
// x forward, y left, z up. All positions below are in that frame.
#include <string>
#include <utility>
#include <vector>

#include "core/math.hpp"
#include "core/yaml.hpp"

namespace syndds::vehicle {

struct ChassisParams {
  double mass_kg = 0.0;
  Vec3 inertia_kgm2 = Vec3::Zero();  // principal moments about the COM (Ixx, Iyy, Izz)
  Vec3 com_m = Vec3::Zero();         // COM in the chassis reference frame
  Vec3 half_extents_m = Vec3(2.4, 1.1, 0.5);  // collision / render box half sizes
  Vec3 box_centre_m = Vec3(0.0, 0.0, 0.4);    // box centre in the chassis reference frame
  double drag_area_m2 = 0.0;  // Cd * A of the full model's aerodynamic drag (0: none)
};

struct AxleParams {
  double x_m = 0.0;                   // axle position along x
  double half_track_m = 0.0;          // wheel centre lateral offset
  double spring_rate_npm = 0.0;       // per wheel
  double damping_nspm = 0.0;          // per wheel
  double travel_m = 0.0;              // total travel (bump + rebound) around the design height
  double preload_n = -1.0;            // spring force at design height; < 0: static load share
  double bump_stop_rate_npm = 0.0;    // stiffness beyond +-travel/2 (0: 20 x spring rate)
  bool steered = false;
  bool driven = true;
  double brake_torque_nm = 0.0;       // per wheel at braking = 1
};

struct WheelParams {
  double radius_m = 0.0;
  double width_m = 0.0;
  double mass_kg = 0.0;               // wheel + tire (+ unsprung hub) per corner
  double spin_inertia_kgm2 = 0.0;     // about the spin axis (rotating parts only)
};

struct SteeringParams {
  double max_angle_deg = 0.0;         // road-wheel angle of the inner wheel at steering = 1
  double rate_deg_s = 0.0;            // steering actuator rate limit (0: none)
};

struct EngineParams {
  std::vector<std::pair<double, double>> torque_map_rpm_nm;  // full-throttle curve
  double idle_rpm = 800.0;
  double max_rpm = 2700.0;
  double inertia_kgm2 = 0.0;          // motor (crank) shaft, pump included
  double motoring_torque_nm = -1.0;   // closed-throttle drag at max_rpm, linear in rpm
                                      // (< 0: 10 % of the peak torque)
};

/// One row of a torque-converter map: value at a speed ratio w_turbine / w_pump in [0, 1].
using ConverterMap = std::vector<std::pair<double, double>>;

struct TransmissionParams {
  std::vector<double> forward_ratios;  // output/input speed ratio per gear (Chrono convention)
  double reverse_ratio = 0.0;
  double upshift_rpm = 0.0;            // turbine (in-gear shaft) speed
  double downshift_rpm = 0.0;
  double shift_time_s = 0.0;           // gear-shift latency: at most one shift per this time
  // Torque converter as Chrono's ChShaftsTorqueConverter: pump torque (w_pump / K(sr))^2,
  // K in rad/s / sqrt(N m); turbine torque TR(sr) times the pump torque. Rows [sr, value],
  // sr from 0 to 1, linear between rows.
  ConverterMap converter_capacity_map;
  ConverterMap converter_torque_ratio_map;
  double ingear_shaft_inertia_kgm2 = 0.0;  // turns at turbine speed, geared to the wheels
};

struct DrivelineParams {
  double final_drive_ratio = 0.0;      // output/input (Chrono convention, < 1 reduces speed)
  double front_torque_share = 0.5;     // central differential split
  double driveshaft_inertia_kgm2 = 0.0;  // gearbox output to final drive
  // Axle differentials: maximum torque bias ratio slow : fast wheel of a Torsen-type
  // limited-slip differential (1: open). The bias grows from 1 to this value as the wheel
  // speeds part by 0.25 to 0.5 rad/s, as in Chrono's simple driveline.
  double axle_differential_bias = 1.0;
  // The same for the centre differential between the axles (applied to the nominal split).
  double centre_differential_bias = 1.0;
};

struct TireParams {
  double friction_scale = 1.0;         // multiplies terrain friction
  double longitudinal_stiffness = 0.0; // N per unit slip ratio, at nominal load
  double cornering_stiffness = 0.0;    // N per rad of slip angle, at nominal load
  double nominal_load_n = 0.0;
  double vertical_stiffness_npm = 0.0;
  double vertical_damping_nspm = 0.0;
  double rolling_resistance = 0.0;     // coefficient
  double relaxation_length_m = 0.25;   // tread deflection relaxation length (full model)
  double stiffness_load_exponent = 0.8;  // slip stiffnesses scale as (Fz / nominal)^exponent
};

/// Parameters only the reduced-order (kinematic bicycle) model uses.
struct ReducedParams {
  double max_drive_force_n = 0.0;      // at zero speed, full throttle
  double max_power_w = 0.0;            // drive force limited to P / v
  double max_brake_decel_mps2 = 0.0;   // at braking = 1 (on high-friction ground)
  double drag_area_m2 = 0.0;           // Cd * A
  double steering_time_constant_s = 0.0;
  double max_speed_mps = 0.0;
};

struct VehicleParams {
  std::string name;
  std::string source_file;
  ChassisParams chassis;
  WheelParams wheels;
  AxleParams front;
  AxleParams rear;
  SteeringParams steering;
  EngineParams engine;
  TransmissionParams transmission;
  DrivelineParams driveline;
  TireParams tire;
  ReducedParams reduced;

  double wheelbase_m() const { return front.x_m - rear.x_m; }
  double track_m() const { return 2.0 * front.half_track_m; }
  /// Mass of the whole vehicle: chassis + four wheels.
  double total_mass_kg() const { return chassis.mass_kg + 4.0 * wheels.mass_kg; }
  /// Full-throttle engine torque at `rpm` (linear interpolation, clamped at the map ends).
  double engine_torque_nm(double rpm) const;
  /// Peak of the full-throttle torque map and the rpm where it occurs.
  std::pair<double, double> engine_peak_torque() const;
  /// x of the whole vehicle's centre of mass (chassis + wheels at their axles).
  double total_com_x_m() const;
  /// Static vertical load on one wheel of the front (rear) axle on level ground: m g b / L / 2.
  double static_wheel_load_n(bool front) const;
  /// Torque-converter capacity factor K(sr) (rad/s / sqrt(N m)) and torque ratio TR(sr),
  /// linear in the maps, sr clamped to [0, 1].
  double converter_capacity(double speed_ratio) const;
  double converter_torque_ratio(double speed_ratio) const;
  /// Inertia of the driveline parts that turn with the wheels in `gear` (0: neutral), reduced
  /// to the differentials' input in wheel units: J_ingear / (ratio final)^2 + J_drive / final^2.
  double driveline_inertia_at_wheels_kgm2(int gear) const;
  /// Closed-throttle engine drag at max_rpm (N m, positive), derived when the file gives < 0.
  double engine_motoring_torque_nm() const;
};

/// Reads and validates a vehicle file; errors name file:line:column and the key.
VehicleParams load_vehicle_params(const std::string& file);
VehicleParams parse_vehicle_params(const YamlNode& root);

}  // namespace syndds::vehicle
