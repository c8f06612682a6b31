#include "vehicle/bicycle_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/hash.hpp"

namespace syndds::vehicle {
namespace {

/// The params this model reads (a state is refused by a vehicle whose params differ in any of
/// them; the full model's own params do not matter here).
std::uint64_t reduced_params_fingerprint(const VehicleParams& p) {
  Fnv1a64 h;
  for (double v : {p.chassis.mass_kg, p.wheels.radius_m, p.wheels.mass_kg, p.front.x_m,
                   p.front.half_track_m, p.rear.x_m, p.rear.half_track_m,
                   p.steering.max_angle_deg, p.engine.idle_rpm, p.tire.friction_scale,
                   p.tire.rolling_resistance, p.reduced.max_drive_force_n, p.reduced.max_power_w,
                   p.reduced.max_brake_decel_mps2, p.reduced.drag_area_m2,
                   p.reduced.steering_time_constant_s, p.reduced.max_speed_mps}) {
    h.add(v);
  }
  h.add(std::int64_t{p.front.steered});
  h.add(std::int64_t{p.rear.steered});
  return h.value();
}

}  // namespace

DriverInputs clamp_inputs(const DriverInputs& in) {
  return DriverInputs{clamp(in.steering, -1.0, 1.0), clamp(in.throttle, 0.0, 1.0),
                      clamp(in.braking, 0.0, 1.0)};
}

BicycleModel::BicycleModel(const VehicleParams& params, const Pose& initial_pose,
                           std::shared_ptr<const terrain::TerrainSurface> terrain)
    : params_(params), terrain_(std::move(terrain)), footprint_(footprint_of(params)) {
  x_ = initial_pose.position.x();
  y_ = initial_pose.position.y();
  yaw_ = yaw_of(initial_pose.orientation);
}

void BicycleModel::set_inputs(const DriverInputs& inputs) { inputs_ = clamp_inputs(inputs); }

void BicycleModel::advance(double dt) {
  const ReducedParams& r = params_.reduced;
  const double mass = params_.total_mass_kg();
  const double wheelbase = params_.wheelbase_m();
  const double mu = terrain_->friction(x_, y_) * params_.tire.friction_scale;

  // Steering: first-order lag toward the commanded road-wheel angle.
  const double target = inputs_.steering * deg_to_rad(params_.steering.max_angle_deg);
  const double tau = r.steering_time_constant_s;
  steer_angle_ += (tau > 0.0 ? std::min(1.0, dt / tau) : 1.0) * (target - steer_angle_);

  // Longitudinal forces. Drive is limited by engine power, by a force cap and by traction.
  const double drive_cap = std::min(r.max_drive_force_n, r.max_power_w / std::max(speed_, 0.5));
  const double drive = std::min(inputs_.throttle * drive_cap, mu * mass * kGravity);
  const double brake = inputs_.braking * mass * std::min(r.max_brake_decel_mps2, mu * kGravity);
  const double resist = params_.tire.rolling_resistance * mass * kGravity +
                        0.5 * kAirDensity * r.drag_area_m2 * speed_ * speed_;
  double accel = drive / mass;
  // Brakes and resistance only oppose motion: they cannot push the vehicle backwards.
  const double opposing = (brake + resist) / mass;
  double new_speed = speed_ + (accel - opposing) * dt;
  if (speed_ + accel * dt <= opposing * dt) new_speed = 0.0;
  new_speed = std::clamp(new_speed, 0.0, r.max_speed_mps);
  accel = (new_speed - speed_) / dt;

  // Kinematic bicycle about the reference point at distance lr ahead of the rear axle.
  const double lr = -params_.rear.x_m;
  const double beta = std::atan(lr * std::tan(steer_angle_) / wheelbase);
  double yaw_rate = new_speed * std::cos(beta) * std::tan(steer_angle_) / wheelbase;
  // Yaw rate limited by lateral friction: v * r <= mu g (the vehicle understeers beyond it).
  const double max_yaw_rate = mu * kGravity / std::max(new_speed, 0.1);
  yaw_rate = std::clamp(yaw_rate, -max_yaw_rate, max_yaw_rate);

  const Vec3 old_velocity(speed_ * std::cos(yaw_ + beta), speed_ * std::sin(yaw_ + beta), 0.0);
  x_ += new_speed * std::cos(yaw_ + beta) * dt;
  y_ += new_speed * std::sin(yaw_ + beta) * dt;
  yaw_ = wrap_angle(yaw_ + yaw_rate * dt);
  const Vec3 new_velocity(new_speed * std::cos(yaw_ + beta), new_speed * std::sin(yaw_ + beta),
                          0.0);
  acceleration_ = (new_velocity - old_velocity) / dt;
  angular_acceleration_ = Vec3(0.0, 0.0, (yaw_rate - yaw_rate_) / dt);
  (void)accel;
  yaw_rate_ = yaw_rate;
  speed_ = new_speed;
  wheel_spin_angle_ = std::fmod(wheel_spin_angle_ + speed_ / params_.wheels.radius_m * dt,
                                2.0 * std::numbers::pi);
  time_s_ += dt;
  if (!peers_.empty() || !peer_episodes_.empty()) {
    resolve_contacts(dt);
    const Vec3 contact_velocity(speed_ * std::cos(yaw_ + beta), speed_ * std::sin(yaw_ + beta),
                                0.0);
    acceleration_ = (contact_velocity - old_velocity) / dt;
  }
}

namespace {
constexpr double kPushShare = 0.5;    // of this vehicle's share of an overlap, removed per step
}  // namespace

Rect2 BicycleModel::own_rect() const {
  Rect2 r;
  r.yaw = yaw_;
  r.centre = Vec2(x_, y_) + footprint_.offset_m * Vec2(std::cos(yaw_), std::sin(yaw_));
  r.half_length = footprint_.half_length_m;
  r.half_width = footprint_.half_width_m;
  return r;
}

void BicycleModel::resolve_contacts(double dt) {
  const double mass = params_.total_mass_kg();
  const double lr = -params_.rear.x_m;
  const double beta = std::atan(lr * std::tan(steer_angle_) / params_.wheelbase_m());
  const Vec2 dir(std::cos(yaw_ + beta), std::sin(yaw_ + beta));
  for (Peer& q : peers_) {
    q.rect.centre += dt * q.velocity;
    q.rect.yaw += dt * q.yaw_rate;
    const Rect2 own = own_rect();
    const RectOverlap ov = rect_overlap(own, q.rect);
    if (ov.depth <= 0.0) continue;
    PeerEpisode& e = peer_episodes_[q.id];
    const Vec2 n = ov.normal;  // from this vehicle to the peer
    const Vec2 u = speed_ * dir;
    const double closing = (u - q.velocity).dot(n);
    const double share = q.mass_kg / (mass + q.mass_kg);
    double impulse = 0.0;
    if (closing > 0.0) {
      impulse = closing * mass * q.mass_kg / (mass + q.mass_kg);
      const Vec2 u_after = u - impulse / mass * n;
      q.velocity += impulse / q.mass_kg * n;
      speed_ = std::clamp(u_after.dot(dir), 0.0, params_.reduced.max_speed_mps);
    }
    // This vehicle's share of the overlap, part of it per step (the other side removes its own).
    const Vec2 push = -kPushShare * share * ov.depth * n;
    x_ += push.x();
    y_ += push.y();
    if (!e.open) {
      CollisionContact c;
      c.other_vehicle = q.id;
      c.impulse_ns = impulse;
      const Vec2 at = own.centre + own.radius_along(n) * n;
      c.position = Vec3(at.x(), at.y(), terrain_->height(at.x(), at.y()));
      c.relative_speed_mps = (u - q.velocity + impulse / q.mass_kg * n).norm();
      collisions_.push_back(std::move(c));
    }
    e.open = true;
    e.last_contact_s = time_s_;
  }
  for (auto& [id, e] : peer_episodes_) {
    if (e.open && time_s_ - e.last_contact_s > kEpisodeGapS) e.open = false;
  }
}

void BicycleModel::set_peers(std::vector<PeerVehicle> peers) {
  peers_.clear();
  for (const PeerVehicle& p : peers) {
    if (!p.params) throw std::invalid_argument("peer vehicle '" + p.id + "' has no params");
    const Footprint f = footprint_of(*p.params);
    const double yaw = yaw_of(p.pose.orientation);
    Peer q;
    q.id = p.id;
    q.rect.yaw = yaw;
    const Vec3 offset = f.offset_m * Vec3(std::cos(yaw), std::sin(yaw), 0.0);
    q.rect.centre = Vec2(p.pose.position.x() + offset.x(), p.pose.position.y() + offset.y());
    q.rect.half_length = f.half_length_m;
    q.rect.half_width = f.half_width_m;
    const Vec3 v = p.linear_velocity + p.angular_velocity.cross(offset);
    q.velocity = Vec2(v.x(), v.y());
    q.yaw_rate = p.angular_velocity.z();
    q.mass_kg = p.params->total_mass_kg();
    peers_.push_back(std::move(q));
  }
}

void BicycleModel::set_speed(double speed_mps) {
  if (!std::isfinite(speed_mps)) throw std::invalid_argument("speed must be finite");
  speed_ = std::clamp(speed_mps, 0.0, params_.reduced.max_speed_mps);
}

std::vector<CollisionContact> BicycleModel::take_collisions() {
  std::vector<CollisionContact> out;
  out.swap(collisions_);
  return out;
}

// Not saved: params_ and terrain_ (the constructor's; the fingerprint checks the params).
void BicycleModel::save_state(core::StateWriter& w) {
  w.begin("bicycle_model", 2);
  w.io(params_.name);
  w.io(reduced_params_fingerprint(params_));
  w.io(inputs_.steering);
  w.io(inputs_.throttle);
  w.io(inputs_.braking);
  w.io(time_s_);
  w.io(x_);
  w.io(y_);
  w.io(yaw_);
  w.io(speed_);
  w.io(steer_angle_);
  w.io(yaw_rate_);
  w.io(wheel_spin_angle_);
  w.io(acceleration_);
  w.io(angular_acceleration_);
  // Since version 2: contact episodes with other vehicles, collisions not taken yet.
  w.io(static_cast<std::uint64_t>(peer_episodes_.size()));
  for (const auto& [id, e] : peer_episodes_) {
    w.io(id);
    w.io(e.last_contact_s);
    w.io(e.open);
  }
  w.io(static_cast<std::uint64_t>(collisions_.size()));
  for (const auto& c : collisions_) {
    w.io(c.other_vehicle);
    w.io(c.impulse_ns);
    w.io(c.position);
    w.io(c.relative_speed_mps);
  }
  w.end();
}

void BicycleModel::load_state(core::StateReader& r) {
  const std::uint32_t version = r.begin("bicycle_model", 2, 1);
  const auto name = r.get<std::string>();
  const auto fingerprint = r.get<std::uint64_t>();
  if (fingerprint != reduced_params_fingerprint(params_)) {
    r.fail("the state is of vehicle '" + name + "' with params fingerprint " + hex64(fingerprint) +
           "; this model is vehicle '" + params_.name + "' with " +
           hex64(reduced_params_fingerprint(params_)) + ": their params differ");
  }
  // Read into a copy and take it only once the whole section has been read: a state that
  // does not fit leaves the model as it was.
  BicycleModel m = *this;
  r.io(m.inputs_.steering);
  r.io(m.inputs_.throttle);
  r.io(m.inputs_.braking);
  r.io(m.time_s_);
  r.io(m.x_);
  r.io(m.y_);
  r.io(m.yaw_);
  r.io(m.speed_);
  r.io(m.steer_angle_);
  r.io(m.yaw_rate_);
  r.io(m.wheel_spin_angle_);
  r.io(m.acceleration_);
  r.io(m.angular_acceleration_);
  m.peer_episodes_.clear();
  m.collisions_.clear();
  if (version >= 2) {
    const auto episodes = r.get<std::uint64_t>();
    for (std::uint64_t k = 0; k < episodes; ++k) {
      const auto id = r.get<std::string>();
      PeerEpisode e;
      r.io(e.last_contact_s);
      r.io(e.open);
      m.peer_episodes_[id] = e;
    }
    const auto pending = r.get<std::uint64_t>();
    for (std::uint64_t k = 0; k < pending; ++k) {
      CollisionContact c;
      r.io(c.other_vehicle);
      r.io(c.impulse_ns);
      r.io(c.position);
      r.io(c.relative_speed_mps);
      m.collisions_.push_back(std::move(c));
    }
  }
  r.end();
  *this = std::move(m);
}

VehicleSnapshot BicycleModel::snapshot() const {
  VehicleSnapshot s;
  s.time_s = time_s_;
  const double z = terrain_->height(x_, y_) + params_.wheels.radius_m;
  s.pose.position = Vec3(x_, y_, z);
  s.pose.orientation = quat_from_yaw(yaw_);
  const double lr = -params_.rear.x_m;
  const double beta = std::atan(lr * std::tan(steer_angle_) / params_.wheelbase_m());
  s.linear_velocity = Vec3(speed_ * std::cos(yaw_ + beta), speed_ * std::sin(yaw_ + beta), 0.0);
  s.angular_velocity = Vec3(0.0, 0.0, yaw_rate_);
  s.linear_acceleration = acceleration_;
  s.angular_acceleration = angular_acceleration_;
  s.inputs = inputs_;
  s.gear = speed_ > 0.0 || inputs_.throttle > 0.0 ? 1 : 0;
  s.engine_speed_rpm = params_.engine.idle_rpm;

  // Wheels at the four corners, front ones steered with Ackermann geometry.
  const double wheelbase = params_.wheelbase_m();
  const double spin = speed_ / params_.wheels.radius_m;
  const struct {
    const AxleParams* axle;
    double side;
  } corners[4] = {{&params_.front, 1.0}, {&params_.front, -1.0}, {&params_.rear, 1.0},
                  {&params_.rear, -1.0}};
  for (const auto& c : corners) {
    WheelSnapshot w;
    const Vec3 local(c.axle->x_m, c.side * c.axle->half_track_m, 0.0);
    w.pose.position = s.pose.position + s.pose.orientation * local;
    double steer = 0.0;
    if (c.axle->steered && std::abs(steer_angle_) > 1e-9) {
      // Ackermann: each wheel points perpendicular to the line to the turn centre.
      const double radius = wheelbase / std::tan(steer_angle_);  // signed, from rear axle
      steer = std::atan(wheelbase / (radius - c.side * c.axle->half_track_m));
    }
    w.steer_angle_rad = steer;
    w.pose.orientation = s.pose.orientation * quat_from_yaw(steer) *
                         Quat(Eigen::AngleAxisd(wheel_spin_angle_, Vec3::UnitY()));
    w.spin_rad_s = spin;
    w.vertical_load_n = params_.total_mass_kg() * kGravity / 4.0;
    s.wheels.push_back(w);
  }
  return s;
}

}  // namespace syndds::vehicle
