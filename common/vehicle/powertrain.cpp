#include "vehicle/powertrain.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace syndds::vehicle {
namespace {
constexpr double kRadPerSToRpm = 60.0 / (2.0 * std::numbers::pi);
constexpr double kIdleAuthority = 0.2;    // max throttle the idle governor may add
constexpr double kIdleBand = 0.1;         // governor reaches full authority 10 % below idle
constexpr double kStoppedMps = 0.1;       // below this, throttle 0 selects neutral
}  // namespace

Powertrain::Powertrain(const VehicleParams& params)
    : params_(params),
      motoring_(params.engine_motoring_torque_nm()) {
  reset();
}

void Powertrain::reset() {
  gear_ = 0;
  engine_speed_ = params_.engine.idle_rpm / kRadPerSToRpm;
  turbine_rpm_ = params_.engine.idle_rpm;
  since_shift_s_ = 1e9;
  engine_torque_ = 0.0;
  turbine_torque_ = 0.0;
}

void Powertrain::save_state(core::StateWriter& w) const {
  w.begin("powertrain", 1);
  w.io(gear_);
  w.io(engine_speed_);
  w.io(turbine_rpm_);
  w.io(since_shift_s_);
  w.io(engine_torque_);
  w.io(turbine_torque_);
  w.end();
}

void Powertrain::load_state(core::StateReader& r) {
  r.begin("powertrain", 1, 1);
  const auto gear = r.get<int>();
  // Reverse is never engaged (no gear selector), so a state can only hold 0..top gear; any
  // other gear would index past the ratios.
  const int top_gear = static_cast<int>(params_.transmission.forward_ratios.size());
  if (gear < 0 || gear > top_gear) {
    r.fail("gear " + std::to_string(gear) + " is not one of this gearbox's 0.." +
           std::to_string(top_gear));
  }
  const auto engine_speed = r.get<double>();
  const auto turbine_rpm = r.get<double>();
  const auto since_shift = r.get<double>();
  const auto engine_torque = r.get<double>();
  const auto turbine_torque = r.get<double>();
  r.end();
  gear_ = gear;
  engine_speed_ = engine_speed;
  turbine_rpm_ = turbine_rpm;
  since_shift_s_ = since_shift;
  engine_torque_ = engine_torque;
  turbine_torque_ = turbine_torque;
}

double Powertrain::engine_rpm() const { return engine_speed_ * kRadPerSToRpm; }

double Powertrain::overall_ratio() const {
  if (gear_ <= 0) return 0.0;
  return params_.transmission.forward_ratios[static_cast<std::size_t>(gear_ - 1)] *
         params_.driveline.final_drive_ratio;
}

double Powertrain::engine_torque(double w_engine, double throttle) const {
  const double rpm = w_engine * kRadPerSToRpm;
  const double idle = params_.engine.idle_rpm;
  const double governor =
      kIdleAuthority * clamp((idle - rpm) / (kIdleBand * idle), 0.0, 1.0);
  const double s = std::max(throttle, governor);
  return s * params_.engine_torque_nm(rpm) -
         (1.0 - s) * motoring_ * std::max(rpm, 0.0) / params_.engine.max_rpm;
}

std::pair<double, double> Powertrain::converter_torques(double w_engine,
                                                        double w_turbine) const {
  const double wp = std::max(w_engine, 0.0);
  if (wp <= 0.0) return {0.0, 0.0};  // Chrono: speed ratio 0 and no pump speed, no torque
  auto forward = [&](double sr) {
    const double k = params_.converter_capacity(sr);
    const double pump = (wp / k) * (wp / k);
    return std::pair{pump, params_.converter_torque_ratio(sr) * pump};
  };
  auto reverse = [&](double sr) {  // the turbine drives the pump, no torque multiplication
    const double k = params_.converter_capacity(1.0 / sr);
    const double pump = -(wp / k) * (wp / k);
    return std::pair{pump, pump};
  };
  const double sr = w_turbine / wp;
  if (sr <= 1.0 - kCouplingBand) return forward(std::max(sr, 0.0));
  if (sr >= 1.0 + kCouplingBand) return reverse(sr);
  const auto lo = forward(1.0 - kCouplingBand);
  const auto hi = reverse(1.0 + kCouplingBand);
  const double t = (sr - (1.0 - kCouplingBand)) / (2.0 * kCouplingBand);
  return {lo.first + t * (hi.first - lo.first), lo.second + t * (hi.second - lo.second)};
}

double Powertrain::step(double throttle, double wheel_speed_rad_s, double vehicle_speed_mps,
                        double dt) {
  const auto& tr = params_.transmission;
  const int top_gear = static_cast<int>(tr.forward_ratios.size());
  since_shift_s_ += dt;

  // Gear selection.
  if (gear_ == 0) {
    if (throttle > 0.0) {
      // Engage the lowest gear whose turbine speed stays below the upshift speed (first gear
      // from standstill; the right gear when the vehicle is already rolling).
      gear_ = 1;
      while (gear_ < top_gear && wheel_speed_rad_s / overall_ratio() * kRadPerSToRpm >
                                     tr.upshift_rpm) {
        ++gear_;
      }
      since_shift_s_ = 0.0;
    }
  } else if (throttle <= 0.0 && std::abs(vehicle_speed_mps) < kStoppedMps) {
    gear_ = 0;
  } else if (since_shift_s_ >= tr.shift_time_s) {
    const double rpm_t = wheel_speed_rad_s / overall_ratio() * kRadPerSToRpm;
    if (rpm_t > tr.upshift_rpm && gear_ < top_gear) {
      ++gear_;
      since_shift_s_ = 0.0;
    } else if (rpm_t < tr.downshift_rpm && gear_ > 1) {
      --gear_;
      since_shift_s_ = 0.0;
    }
  }

  const double ratio = overall_ratio();
  const double w_t = gear_ > 0 ? wheel_speed_rad_s / ratio : 0.0;
  auto net = [&](double w) {
    const double pump = gear_ > 0 ? converter_torques(w, w_t).first : 0.0;
    return (engine_torque(w, throttle) - pump) / params_.engine.inertia_kgm2;
  };
  // Engine speed: backward Euler linearised about the current speed (the converter and the
  // governor region of the map are stiff against the small crankshaft inertia).
  const double w0 = engine_speed_;
  const double f0 = net(w0);
  constexpr double kProbe = 0.5;  // rad/s
  const double df = (net(w0 + kProbe) - f0) / kProbe;
  double w1 = w0 + dt * f0 / (1.0 - dt * std::min(df, 0.0));
  const double w_max = 1.5 * params_.engine.max_rpm / kRadPerSToRpm;
  engine_speed_ = clamp(w1, 0.0, w_max);

  engine_torque_ = engine_torque(engine_speed_, throttle);
  if (gear_ == 0) {
    turbine_rpm_ = engine_rpm();
    turbine_torque_ = 0.0;
    return 0.0;
  }
  turbine_rpm_ = w_t * kRadPerSToRpm;
  turbine_torque_ = converter_torques(engine_speed_, w_t).second;
  return turbine_torque_ / ratio;
}

}  // namespace syndds::vehicle
