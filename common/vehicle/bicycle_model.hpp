#pragma once
// Reduced-order vehicle: kinematic bicycle about the chassis reference point with a
// first-order steering lag, a power-limited drive force, braking, rolling resistance and
// aerodynamic drag, and yaw rate limited by the available lateral friction. Follows the
// terrain height under the reference point. Cheap enough for RL training at scale.
#include "vehicle/vehicle_model.hpp"

namespace syndds::vehicle {

class BicycleModel final : public VehicleModel {
 public:
  BicycleModel(const VehicleParams& params, const Pose& initial_pose,
               std::shared_ptr<const terrain::TerrainSurface> terrain);

  std::string_view kind() const override { return "reduced"; }
  void set_inputs(const DriverInputs& inputs) override;
  void advance(double dt) override;
  VehicleSnapshot snapshot() const override;
  /// Section "bicycle_model" v1: every member below but the params and the terrain (the
  /// constructor's), after the vehicle's name and a fingerprint of the params it reads.
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  double speed_mps() const { return speed_; }
  double road_wheel_angle_rad() const { return steer_angle_; }

 private:
  VehicleParams params_;
  std::shared_ptr<const terrain::TerrainSurface> terrain_;
  DriverInputs inputs_;
  double time_s_ = 0.0;
  double x_ = 0.0, y_ = 0.0, yaw_ = 0.0;
  double speed_ = 0.0;        // along the heading, >= 0
  double steer_angle_ = 0.0;  // bicycle road-wheel angle
  double yaw_rate_ = 0.0;
  double wheel_spin_angle_ = 0.0;
  Vec3 acceleration_ = Vec3::Zero();
  Vec3 angular_acceleration_ = Vec3::Zero();
};

}  // namespace syndds::vehicle
