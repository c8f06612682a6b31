#pragma once
// The per-vertex SCM soil law, split as in MuJoCo into a constant model and mutable data:
// SoilLaw holds the parameters (fixed for the terrain's life, shared by all threads), the
// VertexRecord of vertex_grid.hpp is the per-vertex state it updates each step. One call of
// apply() is one vertex for one step: elastic trial, Bekker-Wong plastic loading, damping,
// stress along the body's surface normal, Janosi-Hanamoto shear through the mobilisation vector.
// The pieces are public so that tests can hold them against the closed forms (docs/scm.md).
#include <cmath>
#include <cstdint>

#include "core/math.hpp"
#include "scm/scm_params.hpp"
#include "scm/vertex_grid.hpp"

namespace syndds::scm {

/// What the law needs to know of the body at a contact vertex.
struct ContactPoint {
  double z_hit = 0.0;            // lowest body point on the vertical through the vertex
  Vec3 arm = Vec3::Zero();       // that point minus the body centre (world)
  Vec3 velocity = Vec3::Zero();  // velocity of the body at that point (world)
  Vec3 normal = -Vec3::UnitZ();  // outward unit normal of the body surface there
  double slope_cap = 0.0;        // largest |n_h / n_z| used (secant slope, see apply())
};

/// Force of one vertex on its body (world frame, about the body centre) and its sinkage.
struct VertexLoad {
  Vec3 force = Vec3::Zero();
  Vec3 torque = Vec3::Zero();
  double sinkage = 0.0;
  bool loaded = false;
};

/// Shear mobilisation after a slip: `m` the state to keep, `force_m` the one the force uses.
struct ShearMobilisation {
  double mx = 0.0, my = 0.0;
  double force_mx = 0.0, force_my = 0.0;
};

class SoilLaw {
 public:
  /// `cell_area_m2` is the horizontal area one vertex carries (spacing squared).
  SoilLaw(const SoilParams& soil, double shear_damping_time_s, double cell_area_m2);

  const SoilParams& soil() const { return soil_; }
  double tan_phi() const { return tan_phi_; }
  double cell_area() const { return cell_area_; }

  /// Bekker-Wong pressure-sinkage, sigma = (kc / b + kphi) s^n, with oob = 1 / b.
  double bekker_pressure(double oob, double sinkage) const {
    return (soil_.bekker_kc * oob + soil_.bekker_kphi) * std::pow(sinkage, soil_.bekker_n);
  }
  /// Mohr-Coulomb shear strength tau_max = c + sigma tan(phi).
  double shear_strength(double sigma) const { return soil_.cohesion_pa + sigma * tan_phi_; }
  /// Mobilisation (mx, my) after a horizontal slip (sx, sy) in a step of length dt.
  ShearMobilisation mobilise(double mx, double my, double sx, double sy, double dt) const;
  /// One step of the law at one vertex; updates `state` (level, sinkage, yield stress, shear
  /// and contact state). `oob` is 1 / b of the vertex's patch, `step` the step index.
  VertexLoad apply(VertexRecord& state, const ContactPoint& point, double oob, std::int64_t step,
                   double dt) const;

 private:
  SoilParams soil_;
  double shear_damping_s_ = 0.0;
  double cell_area_ = 0.0;
  double tan_phi_ = 0.0;
};

}  // namespace syndds::scm
