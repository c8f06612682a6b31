#pragma once
// Terrain seen by vehicle models. Rigid terrain answers height / normal / friction queries and
// the vehicle's tire model turns them into forces. Deformable terrain (SCM) computes the
// wheel-soil forces itself through WheelTerrainContact.
#include <memory>
#include <span>
#include <string>

#include "core/math.hpp"

namespace syndds::terrain {

class TerrainSurface {
 public:
  virtual ~TerrainSurface() = default;
  /// Ground height (m) at world (x, y).
  virtual double height(double x, double y) const = 0;
  /// Unit upward surface normal at world (x, y).
  virtual Vec3 normal(double x, double y) const = 0;
  /// Coulomb friction coefficient of the ground at (x, y).
  virtual double friction(double x, double y) const = 0;
};

/// Horizontal plane z = height_m.
class FlatTerrain final : public TerrainSurface {
 public:
  explicit FlatTerrain(double height_m = 0.0, double friction = 0.8)
      : height_m_(height_m), friction_(friction) {}
  double height(double, double) const override { return height_m_; }
  Vec3 normal(double, double) const override { return Vec3::UnitZ(); }
  double friction(double, double) const override { return friction_; }

 private:
  double height_m_;
  double friction_;
};

/// Kinematic state of one wheel body, input of a deformable-terrain contact computation.
struct WheelBodyState {
  Pose pose;                 // wheel centre; the spin axis is the wheel's local y axis
  Vec3 linear_velocity = Vec3::Zero();   // of the wheel centre, world frame
  Vec3 angular_velocity = Vec3::Zero();  // world frame
  double radius_m = 0.0;
  double width_m = 0.0;
};

/// Force and torque the ground applies to a wheel body (world frame, torque about its centre).
struct WheelLoad {
  Vec3 force = Vec3::Zero();
  Vec3 torque = Vec3::Zero();
  double sinkage_m = 0.0;
  bool in_contact = false;
};

/// Deformable ground (SCM) that computes wheel-soil forces itself and deforms under them.
/// `vehicle_index` tells the terrain which wheel set is which (for per-wheel slip history).
class WheelTerrainContact {
 public:
  virtual ~WheelTerrainContact() = default;
  virtual void compute_wheel_loads(std::span<const WheelBodyState> wheels, double dt,
                                   std::span<WheelLoad> loads) = 0;
};

}  // namespace syndds::terrain
