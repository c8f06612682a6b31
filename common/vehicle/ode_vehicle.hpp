#pragma once
// Full multibody vehicle on ODE: a chassis and four wheel bodies, independent suspension per
// wheel, Ackermann steering, engine + torque converter + automatic gearbox, AWD driveline with
// open differentials, brakes, slip-based tires on rigid ground (or the forces of a deformable
// terrain), and collisions with static obstacles. docs/vehicle-dynamics.md describes the model.
//
// The ODE world is private to each instance (ODE headers are not exposed here); several
// instances can live and step in one process and give bit-identical results run to run.
// One instance must not be used from two threads at once; stepping different instances from
// different threads at the same time is untested (Debian's ODE is built without per-thread
// collision data), so keep them on one thread.
#include <array>
#include <memory>

#include "terrain/terrain.hpp"
#include "vehicle/vehicle_model.hpp"
#include "world/obstacle.hpp"

namespace syndds::vehicle {

class OdeVehicleModel final : public VehicleModel {
 public:
  /// Builds the vehicle at start (x, y, yaw; z is ignored: the vehicle is placed on the terrain)
  /// and settles it with the brakes on, so that time 0 is at rest. If `deformable` is given,
  /// wheel-ground forces come from it instead of the tire model (settling included).
  OdeVehicleModel(const VehicleParams& params, const Pose& start,
                  std::shared_ptr<const terrain::TerrainSurface> terrain,
                  const world::Obstacles& obstacles = {},
                  std::shared_ptr<terrain::WheelTerrainContact> deformable = nullptr);
  ~OdeVehicleModel() override;
  OdeVehicleModel(const OdeVehicleModel&) = delete;
  OdeVehicleModel& operator=(const OdeVehicleModel&) = delete;

  std::string_view kind() const override { return "full"; }
  /// Clamps to the ranges; throws std::invalid_argument on NaN or infinite values.
  void set_inputs(const DriverInputs& inputs) override;
  /// One dynamics step. Throws std::runtime_error if the state stops being finite.
  void advance(double dt) override;
  VehicleSnapshot snapshot() const override;
  /// Obstacle hits since the last call, one per episode, reported in the step contact began:
  /// impulse = normal contact impulse of that first step (ODE contacts are velocity
  /// constraints, so this is most of the hit), position = first contact point. An episode
  /// lasts until the vehicle has been free of the obstacle for 0.5 s and is out of its reach.
  std::vector<CollisionContact> take_collisions() override;
  /// Each peer becomes a rigid body of its whole mass and inertia (chassis plus wheels at their
  /// design places) carrying its chassis box and its wheel cylinders at the given wheel poses,
  /// without gravity, moving on with its velocities and the reactions of this vehicle's contact
  /// forces until the next call (docs/vehicle-contact.md). A vehicle-vehicle collision episode
  /// is reported like an obstacle's, with the other vehicle's id and the relative speed.
  void set_peers(std::vector<PeerVehicle> peers) override;
  /// Section "ode_vehicle" v1 (docs/vehicle-dynamics.md, "Checkpoint state"): the bodies as
  /// ODE holds them, powertrain, tires, inputs, collision episodes, after fingerprints of the
  /// params, the placement and the obstacles that load_state checks. save_state passes the
  /// bodies through ODE's setters (which normalise the quaternions again), as load_state does.
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  /// Sets the vehicle rolling straight ahead at `forward_speed_mps` (chassis and wheels, tire
  /// states reset), e.g. to start a scenario or a test at speed. Positions are kept.
  void set_speed(double forward_speed_mps);

  /// Per-wheel internals for tests and diagnostics (FL, FR, RL, RR), as of the last step.
  struct WheelDiagnostics {
    double suspension_compression_m = 0.0;  // from design height, positive = bump
    double spring_force_n = 0.0;            // spring + damper + preload + bump stop
    double tire_normal_force_n = 0.0;
    double tire_deflection_m = 0.0;         // radial, rigid ground only
    double slip_ratio = 0.0;
    double slip_angle_rad = 0.0;
    double drive_torque_nm = 0.0;
    bool in_contact = false;
  };
  std::array<WheelDiagnostics, 4> wheel_diagnostics() const;
  const VehicleParams& params() const;
  double time_s() const;
  /// Simulated time spent settling in the constructor (before time 0): the load ramps up over
  /// kSettleRampS, then holds.
  static constexpr double kSettleTimeS = 4.0;
  static constexpr double kSettleRampS = 3.0;

  // ---- the test oracle of vehicle-vehicle contact -----------------------------------------
  /// A second vehicle built in `host`'s ODE world (settled while the host is held still), to be
  /// stepped with it by step_pair. Destroy it before the host.
  static std::unique_ptr<OdeVehicleModel> in_world_of(
      OdeVehicleModel& host, const VehicleParams& params, const Pose& start,
      std::shared_ptr<const terrain::TerrainSurface> terrain);
  /// One step of two vehicles sharing one world: both vehicles' own forces, their contact with
  /// each other solved exactly in the same LCP (no frame lag, no proxy), one world step. Their
  /// contact with each other is not reported as a collision.
  static void step_pair(OdeVehicleModel& a, OdeVehicleModel& b, double dt);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  OdeVehicleModel() = default;
};

}  // namespace syndds::vehicle
