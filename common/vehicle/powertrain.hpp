#pragma once
// Engine + torque converter + automatic gearbox + final drive of the full vehicle (no ODE
// here: it takes the driveline speed and returns the torque at the wheels). Structure and
// maps as Chrono::Vehicle's shafts powertrain (ChEngineShafts + ChAutomaticTransmissionShafts).
//
// - Engine: one speed state, J dw/dt = T_engine - T_pump (J: motor shaft inertia).
//   T_engine = s T_full(rpm) - (1 - s) T_motoring rpm / max_rpm, s = max(throttle, idle
//   governor).
// - Torque converter (Chrono's ChShaftsTorqueConverter), speed ratio sr = w_turbine / w_pump:
//     sr <= 1 - b:  T_pump = (w_pump / K(sr))^2,       T_turbine = TR(sr) T_pump
//     sr >= 1 + b:  reverse flow, T_pump = -(w_pump / K(1 / sr))^2,  T_turbine = T_pump
//   with K (rad/s / sqrt(N m)) and TR the maps of the vehicle file, sr < 0 read as 0.
//   Chrono's converter jumps from +(w/K(1))^2 to -(w/K(1))^2 at sr = 1, which makes the
//   engine and the wheels chatter around the coupling point; here both torques are linear in
//   sr across the band |sr - 1| < b (b = kCouplingBand = 0.01), so they pass through zero.
// - Gearbox: Chrono's convention, ratio = output / input speed. Upshift when the turbine
//   exceeds upshift_rpm, downshift below downshift_rpm, at most one shift per shift_time_s
//   (Chrono's gear-shift latency). Neutral (gear 0) while throttle is 0 and the vehicle is
//   (nearly) stopped; with throttle > 0 it engages the lowest gear whose turbine speed is below
//   upshift_rpm (first gear from standstill). DriverInputs have no gear selector, so reverse
//   is never engaged.
// - Shaft inertias of the in-gear shaft and the drive shaft are not states here: they turn
//   with the wheels, and driveline_inertia_at_wheels() gives them to the vehicle model.
#include "core/state_io.hpp"
#include "vehicle/vehicle_params.hpp"

namespace syndds::vehicle {

class Powertrain {
 public:
  explicit Powertrain(const VehicleParams& params);

  /// Advances by dt. `wheel_speed_rad_s` is the driveline speed seen at the wheels (centre
  /// differential input in wheel units), `vehicle_speed_mps` the forward speed.
  /// Returns the total drive torque at the wheels (N m), to be split by the differentials.
  double step(double throttle, double wheel_speed_rad_s, double vehicle_speed_mps, double dt);
  /// Neutral, engine at idle, shift timer cleared.
  void reset();
  /// Checkpoint state (section "powertrain" v1): gear, engine speed, time since the last shift
  /// and the last step's outputs (turbine speed, engine and turbine torque: step() overwrites
  /// them, they are saved so the getters agree after a restore). The params and the motoring
  /// torque derived from them are the constructor's; the owner checks they match. load_state
  /// throws core::StateError on a gear this gearbox does not have, and changes nothing then.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

  int gear() const { return gear_; }
  double engine_rpm() const;
  double turbine_rpm() const { return turbine_rpm_; }
  double engine_torque_nm() const { return engine_torque_; }
  double turbine_torque_nm() const { return turbine_torque_; }
  /// Overall speed ratio wheel / turbine of the current gear (0 in neutral).
  double overall_ratio() const;

  /// Converter torques for engine speed w_e and turbine speed w_t (rad/s): (pump, turbine).
  std::pair<double, double> converter_torques(double w_engine, double w_turbine) const;
  /// Inertia turning with the wheels in the current gear, at the differentials' input in
  /// wheel units (kg m2): in-gear shaft (in gear only) and drive shaft.
  double driveline_inertia_at_wheels() const {
    return params_.driveline_inertia_at_wheels_kgm2(gear_);
  }
  /// Half width of the band around sr = 1 where the converter torques are blended.
  static constexpr double kCouplingBand = 0.01;
  /// Engine torque at w_e (rad/s) for a throttle, including the idle governor.
  double engine_torque(double w_engine, double throttle) const;

 private:
  VehicleParams params_;
  double motoring_ = 0.0;        // N m at max_rpm
  int gear_ = 0;
  double engine_speed_ = 0.0;    // rad/s
  double turbine_rpm_ = 0.0;
  double since_shift_s_ = 1e9;
  double engine_torque_ = 0.0;
  double turbine_torque_ = 0.0;
};

}  // namespace syndds::vehicle
