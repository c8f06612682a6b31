#pragma once
// The interface every vehicle dynamics model implements (reduced-order bicycle, full ODE
// multibody). A model owns its state, takes driver inputs, advances by one step, and reports
// a snapshot; it knows nothing of DDS or frames.
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/math.hpp"
#include "core/state_io.hpp"
#include "terrain/terrain.hpp"
#include "vehicle/vehicle_params.hpp"

namespace syndds::vehicle {

struct DriverInputs {
  double steering = 0.0;  // [-1, 1], positive turns left
  double throttle = 0.0;  // [0, 1]
  double braking = 0.0;   // [0, 1]
};

struct WheelSnapshot {
  Pose pose;
  double spin_rad_s = 0.0;
  double steer_angle_rad = 0.0;
  double vertical_load_n = 0.0;
};

struct VehicleSnapshot {
  double time_s = 0.0;
  Pose pose;                                   // chassis reference frame
  Vec3 linear_velocity = Vec3::Zero();         // world frame
  Vec3 angular_velocity = Vec3::Zero();        // world frame
  Vec3 linear_acceleration = Vec3::Zero();     // world frame, over the last step
  Vec3 angular_acceleration = Vec3::Zero();
  std::vector<WheelSnapshot> wheels;           // FL, FR, RL, RR
  DriverInputs inputs;                         // as applied (after clamping and rate limits)
  int gear = 0;                                // 0 neutral, 1.. forward, -1 reverse
  double engine_speed_rpm = 0.0;
  double speed_mps() const { return linear_velocity.norm(); }
};

/// The start of a collision episode: with a static obstacle (`obstacle_id`) or with another
/// vehicle (`other_vehicle`; exactly one of the two is set).
struct CollisionContact {
  std::string obstacle_id;
  double impulse_ns = 0.0;       // normal contact impulse of the step the episode began in
  Vec3 position = Vec3::Zero();  // first contact point
  std::string other_vehicle;
  double relative_speed_mps = 0.0;  // other vehicle only: speed of the contact point on this
                                    // vehicle relative to the one on the other, before the step
};

/// Air density of the aerodynamic drag both models apply (kg/m^3).
inline constexpr double kAirDensity = 1.2;

/// A collision episode with an obstacle ends when the vehicle has been free of it for this long
/// (s); the full model also waits until the obstacle is outside its broad-phase sphere, so front
/// and rear wheels rolling over one rock, or pushing against a wall, make one episode.
inline constexpr double kEpisodeGapS = 0.5;

/// The ground-plane rectangle that holds a vehicle's collision shapes (chassis box and wheels
/// at full steer) about its reference point, in the vehicle's heading frame: the centre lies
/// `offset_m` ahead of the reference point. Broad phase of vehicle-vehicle contact.
struct Footprint {
  double offset_m = 0.0;
  double half_length_m = 0.0;
  double half_width_m = 0.0;
};
Footprint footprint_of(const VehicleParams& params);

/// Another vehicle as this one's contact step sees it (docs/vehicle-contact.md): its collision
/// shapes (from its params) at the state the frame contract gives, i.e. stamped k-1, the start
/// of the frame being stepped. Within the frame a model may move it on with these velocities
/// and the reactions of its own contact forces, never with its own engine, brakes or tires.
struct PeerVehicle {
  std::string id;
  std::shared_ptr<const VehicleParams> params;
  Pose pose;                              // chassis reference frame
  Vec3 linear_velocity = Vec3::Zero();    // of the reference point, world frame
  Vec3 angular_velocity = Vec3::Zero();   // world frame
  std::vector<Pose> wheels;               // FL, FR, RL, RR centres (empty: design positions)
};

class VehicleModel {
 public:
  virtual ~VehicleModel() = default;
  virtual std::string_view kind() const = 0;
  /// Inputs for the following steps; values are clamped to their ranges.
  virtual void set_inputs(const DriverInputs& inputs) = 0;
  /// Advances the model by dt seconds (one dynamics step).
  virtual void advance(double dt) = 0;
  virtual VehicleSnapshot snapshot() const = 0;
  /// Collisions that started since the last call (each contact episode reported once).
  virtual std::vector<CollisionContact> take_collisions() { return {}; }
  /// The other vehicles this one can touch in the steps until the next call (sorted by id, none
  /// of them this vehicle). Forces act on this model's own bodies only; the other vehicle's
  /// process computes the same contact from its side (action and reaction up to what one
  /// frame's proxy leaves out). A model without vehicle contact ignores them.
  virtual void set_peers(std::vector<PeerVehicle> peers) { (void)peers; }

  // ---- checkpoints (docs/checkpoints.md, docs/vehicle-dynamics.md "Checkpoint state") ----
  /// Writes everything that decides the following steps (called between steps): the model's
  /// state, the inputs in force, collisions not yet taken. Afterwards the model continues from
  /// exactly the state load_state rebuilds from these bytes: a model whose own setters round
  /// (ODE normalises quaternions) passes its state through them here, so a run that saves and
  /// a run restored from its bytes step the same numbers, bit for bit.
  virtual void save_state(core::StateWriter& w) = 0;
  /// Restores a state written by save_state. Call it on a model constructed with the same
  /// params, start, terrain and obstacles (after its constructor, i.e. after settling), before
  /// any step. Throws core::StateError (naming what does not fit: another kind of model,
  /// another vehicle's params, other obstacles, truncated bytes) and then leaves the model as
  /// it was.
  virtual void load_state(core::StateReader& r) = 0;
};

/// Clamps driver inputs to their ranges (steering [-1,1], throttle and braking [0,1]).
DriverInputs clamp_inputs(const DriverInputs& in);

}  // namespace syndds::vehicle
