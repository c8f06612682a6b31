#include "scm/soil_law.hpp"

#include <algorithm>
#include <cmath>

namespace syndds::scm {

SoilLaw::SoilLaw(const SoilParams& soil, double shear_damping_time_s, double cell_area_m2)
    : soil_(soil),
      shear_damping_s_(shear_damping_time_s),
      cell_area_(cell_area_m2),
      tan_phi_(std::tan(deg_to_rad(soil.friction_angle_deg))) {}

// Shear mobilisation m = tau / tau_max (a horizontal vector, |m| <= 1) follows the slip path of
// the body point over the soil: dm = (e - m) ds / K, e the slip direction and ds the slip length
// (exact for a step of constant velocity). Monotonic slip j gives |m| = 1 - exp(-j / K),
// Janosi-Hanamoto; at rest m keeps its value (a stiff spring of tangent stiffness tau_max / K,
// no chatter) and a reversal unwinds it.
ShearMobilisation SoilLaw::mobilise(double mx, double my, double sx, double sy, double dt) const {
  ShearMobilisation out;
  const double ds = std::hypot(sx, sy);
  double fmx = mx, fmy = my;  // mobilisation the force uses (see the shear damping below)
  if (ds > 0.0) {
    const double ex = sx / ds, ey = sy / ds;
    const double decay = std::exp(-ds / soil_.janosi_shear_m);
    mx = ex + (mx - ex) * decay;
    my = ey + (my - ey) * decay;
    // Shear damping: the force takes the mobilisation reached after a further slip
    // |v_t| * beta, i.e. stiffness-proportional damping tau_max (e - m) |v_t| beta / K for
    // small slips, bounded by the Mohr-Coulomb strength (|m| <= 1).
    const double ahead = std::exp(-(ds / dt) * shear_damping_s_ / soil_.janosi_shear_m);
    fmx = ex + (mx - ex) * ahead;
    fmy = ey + (my - ey) * ahead;
  }
  out.mx = mx;
  out.my = my;
  out.force_mx = fmx;
  out.force_my = fmy;
  return out;
}

VertexLoad SoilLaw::apply(VertexRecord& r, const ContactPoint& point, double oob, std::int64_t step,
                          double dt) const {
  VertexLoad out;
  const double ke = soil_.elastic_stiffness_pa_per_m;
  const double sinkage = r.level_initial - point.z_hit;
  double sigma = ke * (sinkage - r.sinkage_plastic);  // elastic trial
  if (!(sigma > 0.0)) return out;                     // unilateral: no tension
  const Vec3& vel = point.velocity;
  const double vn = vel.z();
  double mx = 0.0, my = 0.0;  // the mobilisation survives only an unbroken contact
  if (r.contact_step == step - 1) {
    mx = r.shear_x;
    my = r.shear_y;
  }
  const ShearMobilisation m = mobilise(mx, my, vel.x() * dt, vel.y() * dt, dt);
  r.level = point.z_hit;
  r.step_plastic_flow = 0.0;
  if (sigma > r.sigma_yield) {  // plastic: follow the Bekker curve
    sigma = bekker_pressure(oob, sinkage);
    r.sigma_yield = sigma;
    const double old_plastic = r.sinkage_plastic;
    r.sinkage_plastic = sinkage - sigma / ke;
    r.step_plastic_flow = r.sinkage_plastic - old_plastic;
  }
  // Damping (Chrono's, of the vertical motion): the total stress, clamped at zero, acts
  // vertically; of it, the soil stress (without the compressive damping) acts along the
  // body's outward surface normal n, as the radial stress of Bekker and Wong on a rigid
  // wheel. sigma is per unit horizontal area (the Bekker plate law), so that part adds the
  // horizontal sigma_n * (-n_h / |n_z|), the slope of the body surface over the vertex,
  // capped at the secant slope of the body's outline over its last grid cell (the cell is
  // not small against the body there).
  const double damped = sigma - vn * soil_.damping_pa_s_per_m;
  const double sigma_n = std::max(0.0, std::min(sigma, damped));
  sigma = std::max(0.0, damped);
  double gx = 0.0, gy = 0.0;
  const Vec3& n = point.normal;
  if (n.z() < 0.0) {
    gx = n.x() / n.z();
    gy = n.y() / n.z();
    const double slope = std::hypot(gx, gy);
    if (slope > point.slope_cap) {
      gx *= point.slope_cap / slope;
      gy *= point.slope_cap / slope;
    }
  }
  const double tau_max = shear_strength(sigma);
  const Vec3 force(cell_area_ * (sigma_n * gx - tau_max * m.force_mx),
                   cell_area_ * (sigma_n * gy - tau_max * m.force_my), cell_area_ * sigma);
  r.shear_x = m.mx;
  r.shear_y = m.my;
  r.sigma = sigma;
  r.contact_step = step;
  out.force = force;
  out.torque = point.arm.cross(force);
  out.sinkage = sinkage;
  out.loaded = true;
  return out;
}

}  // namespace syndds::scm
