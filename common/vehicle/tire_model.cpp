#include "vehicle/tire_model.hpp"

#include <algorithm>
#include <cmath>

namespace syndds::vehicle {
namespace {
constexpr double kLowSpeedMps = 2.0;    // the low-speed damping fades out by this speed
constexpr double kSaturationPsi = 3.0;  // brush model: full sliding at psi = 3

double brush_curve(double psi) {
  if (psi >= kSaturationPsi) return 1.0;
  return psi * (1.0 - psi / 3.0 + psi * psi / 27.0);
}
}  // namespace

TireModel::TireModel(const TireParams& tire, const WheelParams& wheel) : p_(tire) {
  // Critical damping of the tread spring (C_kappa / sigma at nominal load) against the wheel's
  // spin inertia seen at the ground (J / r^2): damps the standstill spring without making the
  // explicit spin update stiff.
  const double k = p_.longitudinal_stiffness / p_.relaxation_length_m;
  const double m = wheel.spin_inertia_kgm2 / (wheel.radius_m * wheel.radius_m);
  low_speed_damping_nspm_ = 2.0 * std::sqrt(k * m);
}

double TireModel::normal_force(double deflection_m, double deflection_rate_mps) const {
  if (deflection_m <= 0.0) return 0.0;
  return std::max(0.0, p_.vertical_stiffness_npm * deflection_m +
                           p_.vertical_damping_nspm * deflection_rate_mps);
}

double TireModel::longitudinal_stiffness(double fz) const {
  if (fz <= 0.0) return 0.0;
  return p_.longitudinal_stiffness * std::pow(fz / p_.nominal_load_n, p_.stiffness_load_exponent);
}

double TireModel::cornering_stiffness(double fz) const {
  if (fz <= 0.0) return 0.0;
  return p_.cornering_stiffness * std::pow(fz / p_.nominal_load_n, p_.stiffness_load_exponent);
}

TireForce TireModel::update(const TireKinematics& k, double dt, TireState& s) const {
  TireForce out;
  if (k.normal_force_n <= 0.0) {
    s = TireState{};  // off the ground the tread relaxes at once
    return out;
  }
  const double sigma = p_.relaxation_length_m;
  // Deflection update, implicit in the relaxation term (stable for any speed and step).
  const double relax = 1.0 + std::abs(k.ground_speed_mps) * dt / sigma;
  s.deflection_x_m = (s.deflection_x_m - k.slip_velocity_x_mps * dt) / relax;
  s.deflection_y_m = (s.deflection_y_m - k.slip_velocity_y_mps * dt) / relax;

  const double ckappa = longitudinal_stiffness(k.normal_force_n);
  const double calpha = cornering_stiffness(k.normal_force_n);
  const double fmax = k.friction * k.normal_force_n;
  if (fmax <= 0.0) {
    s = TireState{};
    return out;
  }
  // No wind-up: while sliding, the deflection stays where the brush curve saturates.
  double fx_def = ckappa * s.deflection_x_m / sigma;
  double fy_def = calpha * s.deflection_y_m / sigma;
  const double psi_def = std::hypot(fx_def, fy_def) / fmax;
  if (psi_def > kSaturationPsi) {
    const double scale = kSaturationPsi / psi_def;
    s.deflection_x_m *= scale;
    s.deflection_y_m *= scale;
    fx_def *= scale;
    fy_def *= scale;
  }
  const double blend = std::max(0.0, 1.0 - std::abs(k.ground_speed_mps) / kLowSpeedMps);
  const double damping = blend * low_speed_damping_nspm_;
  const double fx_lin = fx_def - damping * k.slip_velocity_x_mps;
  const double fy_lin = fy_def - damping * k.slip_velocity_y_mps;
  const double f_lin = std::hypot(fx_lin, fy_lin);
  out.slip_ratio = s.deflection_x_m / sigma;
  out.slip_angle_rad = std::atan(-s.deflection_y_m / sigma);
  if (f_lin <= 0.0) return out;
  const double psi = f_lin / fmax;
  const double scale = fmax * brush_curve(psi) / f_lin;
  out.fx_n = fx_lin * scale;
  out.fy_n = fy_lin * scale;
  out.sliding = psi >= kSaturationPsi;
  return out;
}

}  // namespace syndds::vehicle
