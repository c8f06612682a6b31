#pragma once
// Reduced-order vehicle: kinematic bicycle about the chassis reference point with a
// first-order steering lag, a power-limited drive force, braking, rolling resistance and
// aerodynamic drag, and yaw rate limited by the available lateral friction. Follows the
// terrain height under the reference point. Cheap enough for RL training at scale.
#include <map>

#include "core/rect2.hpp"
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
  std::vector<CollisionContact> take_collisions() override;
  /// Planar contact (docs/vehicle-contact.md): each peer is its footprint rectangle moving on
  /// with its velocities; an overlap after a step is resolved by a perfectly inelastic impulse
  /// along the separating axis shared by the two masses (this model keeps the part along its
  /// heading, never reversing) and by this vehicle's mass share of the overlap, pushed out.
  void set_peers(std::vector<PeerVehicle> peers) override;
  /// Sets the speed along the heading (e.g. to start a test at speed).
  void set_speed(double speed_mps);
  /// Section "bicycle_model" v2: every member below but the params, the terrain, the footprint
  /// and the peers (the constructor's, and the next frame's inputs), after the vehicle's name
  /// and a fingerprint of the params it reads.
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

  struct Peer {
    std::string id;
    Rect2 rect;                 // its footprint, moved on every step
    Vec2 velocity = Vec2::Zero();  // of the footprint centre
    double yaw_rate = 0.0;
    double mass_kg = 0.0;
  };
  struct PeerEpisode {
    double last_contact_s = -1e300;
    bool open = false;
  };
  /// Moves the peers by dt and resolves this vehicle's overlaps with them.
  void resolve_contacts(double dt);
  Rect2 own_rect() const;

  Footprint footprint_;
  std::vector<Peer> peers_;
  std::map<std::string, PeerEpisode> peer_episodes_;
  std::vector<CollisionContact> collisions_;
};

}  // namespace syndds::vehicle
