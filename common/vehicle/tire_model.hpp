#pragma once
// Slip-based tire model of the full vehicle on rigid ground (no ODE here: plain numbers in,
// forces out, so it can be tested on its own). See docs/vehicle-dynamics.md for the equations.
//
// - Normal force: linear spring-damper on the tire's radial deflection, never pulling.
// - Slips: a tread-deflection (relaxation length) model. Each tire carries a longitudinal and a
//   lateral deflection u that follows  du/dt = -v_slip - |v_x| u / sigma.  In steady rolling
//   u / sigma is exactly the slip ratio kappa = (omega r - v_x) / |v_x| (resp. -tan(alpha));
//   at standstill u is a spring that holds the vehicle, so a resting vehicle does not creep
//   and the model has no 0/0 at zero speed.
// - Forces: Fx = C_kappa(Fz) u_x / sigma, Fy = C_alpha(Fz) u_y / sigma, plus a low-speed
//   damping that fades out by 2 m/s; stiffnesses scale as (Fz / Fz0)^e. Combined slip
//   saturation with the brush-model curve on the resultant:
//     psi = |F_lin| / (mu Fz),  |F| = mu Fz (psi - psi^2/3 + psi^3/27) for psi < 3, mu Fz beyond,
//   along the direction of F_lin. When psi > 3 the deflection is clamped (no wind-up).
#include "vehicle/vehicle_params.hpp"

namespace syndds::vehicle {

/// Per-tire state carried from step to step.
struct TireState {
  double deflection_x_m = 0.0;  // longitudinal tread deflection
  double deflection_y_m = 0.0;  // lateral tread deflection
};

/// Contact kinematics of one tire in its contact frame (x forward along the ground, y left).
struct TireKinematics {
  double normal_force_n = 0.0;       // Fz >= 0
  double ground_speed_mps = 0.0;     // v_x: wheel-centre velocity along the tire's x
  double slip_velocity_x_mps = 0.0;  // contact-point velocity along x: v_x - omega r_eff
  double slip_velocity_y_mps = 0.0;  // contact-point velocity along y
  double friction = 0.8;             // mu (terrain friction x tire friction scale)
};

struct TireForce {
  double fx_n = 0.0;            // along the tire's x
  double fy_n = 0.0;            // along the tire's y
  double slip_ratio = 0.0;      // transient slip ratio u_x / sigma
  double slip_angle_rad = 0.0;  // transient slip angle atan(-u_y / sigma)
  bool sliding = false;         // saturated (psi >= 3)
};

class TireModel {
 public:
  TireModel(const TireParams& tire, const WheelParams& wheel);

  /// Normal force from the radial deflection (m) and its rate (m/s, positive compressing).
  double normal_force(double deflection_m, double deflection_rate_mps) const;
  /// Advances the tire's deflection state by dt and returns the ground force on the tire.
  TireForce update(const TireKinematics& k, double dt, TireState& state) const;
  /// Longitudinal (cornering) slip stiffness at a normal load, N per unit slip (per rad).
  double longitudinal_stiffness(double normal_force_n) const;
  double cornering_stiffness(double normal_force_n) const;

 private:
  TireParams p_;
  double low_speed_damping_nspm_ = 0.0;
};

}  // namespace syndds::vehicle
