#include "sensors/interoceptive.hpp"

#include <cmath>
#include <numbers>

#include "core/state_io.hpp"

namespace syndds::sensors {

Vec3 NoiseModel3::apply(const Vec3& truth, double dt, NormalRng& rng) {
  Vec3 out;
  for (int a = 0; a < 3; ++a) {
    // Draw order is fixed (walk then white, axis by axis) so streams are reproducible.
    bias_[a] += rng.normal(config_.walk_per_sqrt_s[a] * std::sqrt(dt));
    out[a] = truth[a] + bias_[a] + rng.normal(config_.white_std[a]);
  }
  return out;
}

double compass_heading(const Quat& orientation) {
  const Vec3 forward = orientation * Vec3::UnitX();
  double h = std::atan2(forward.x(), forward.y());  // east over north: clockwise from north
  if (h < 0.0) h += 2.0 * std::numbers::pi;
  return h;
}

GpsSensor::GpsSensor(const GpsConfig& config, const Geodetic& origin, std::uint64_t seed,
                     double tick_s)
    : PeriodicSensor(config.rate_hz, config.lag_s, tick_s, config.id),
      config_(config),
      converter_(origin, config.model),
      rng_(seed),
      noise_(config.noise) {}

void GpsSensor::update(const vehicle::VehicleSnapshot& state) {
  tick(state.time_s, [&](double dt) {
    GpsSample s;
    s.sensor_id = config_.id;
    s.true_enu_m = state.pose.position + state.pose.orientation * config_.mount.pose.position;
    s.enu_m = noise_.apply(s.true_enu_m, dt, rng_);
    s.position = converter_.to_geodetic(s.enu_m);
    return s;
  });
}

ImuSensor::ImuSensor(const ImuConfig& config, std::uint64_t seed, double tick_s)
    : PeriodicSensor(config.rate_hz, config.lag_s, tick_s, config.id),
      config_(config),
      rng_(seed),
      accel_noise_(config.accelerometer),
      gyro_noise_(config.gyroscope) {}

void ImuSensor::update(const vehicle::VehicleSnapshot& state) {
  tick(state.time_s, [&](double dt) {
    const Quat& q = state.pose.orientation;
    const Quat sensor_q = q * config_.mount.pose.orientation;
    const Vec3 r = q * config_.mount.pose.position;  // lever arm, world frame
    const Vec3& w = state.angular_velocity;
    // Acceleration of the mounting point, then specific force f = a - g_vec (g_vec = -g z).
    const Vec3 a_point =
        state.linear_acceleration + state.angular_acceleration.cross(r) + w.cross(w.cross(r));
    const Vec3 specific_force = a_point + Vec3(0.0, 0.0, kGravity);
    ImuSample s;
    s.sensor_id = config_.id;
    s.accel_mps2 = accel_noise_.apply(sensor_q.conjugate() * specific_force, dt, rng_);
    s.gyro_rad_s = gyro_noise_.apply(sensor_q.conjugate() * w, dt, rng_);
    return s;
  });
}

MagnetometerSensor::MagnetometerSensor(const MagnetometerConfig& config, std::uint64_t seed,
                                       double tick_s)
    : PeriodicSensor(config.rate_hz, config.lag_s, tick_s, config.id), config_(config), rng_(seed) {
  const double dec = deg_to_rad(config.declination_deg);
  const double inc = deg_to_rad(config.inclination_deg);
  world_field_ = config.field_strength_ut *
                 Vec3(std::cos(inc) * std::sin(dec), std::cos(inc) * std::cos(dec), -std::sin(inc));
}

void MagnetometerSensor::update(const vehicle::VehicleSnapshot& state) {
  tick(state.time_s, [&](double) {
    const Quat sensor_q = state.pose.orientation * config_.mount.pose.orientation;
    MagnetometerSample s;
    s.sensor_id = config_.id;
    double h = compass_heading(sensor_q) + rng_.normal(config_.heading_noise_std_rad);
    h = std::fmod(h, 2.0 * std::numbers::pi);
    if (h < 0.0) h += 2.0 * std::numbers::pi;
    s.heading_rad = h;
    const Vec3 body = sensor_q.conjugate() * world_field_;
    for (int a = 0; a < 3; ++a) s.field_ut[a] = body[a] + rng_.normal(config_.field_noise_std_ut);
    return s;
  });
}

TachometerSensor::TachometerSensor(const TachometerConfig& config, std::uint64_t seed,
                                   double tick_s)
    : PeriodicSensor(config.rate_hz, config.lag_s, tick_s, config.id),
      config_(config),
      rng_(seed) {}

void TachometerSensor::update(const vehicle::VehicleSnapshot& state) {
  tick(state.time_s, [&](double) {
    TachometerSample s;
    s.sensor_id = config_.id;
    s.wheel_spin_rad_s.reserve(state.wheels.size());
    for (const auto& w : state.wheels) {
      s.wheel_spin_rad_s.push_back(w.spin_rad_s + rng_.normal(config_.noise_std_rad_s));
    }
    return s;
  });
}

// ---- Checkpoints ---------------------------------------------------------------------------

// One field list per sample type, for both directions (a writer only reads the sample).
template <typename Archive>
void sample_fields(Archive& a, GpsSample& s) {
  a.io(s.sensor_id);
  a.io(s.stamp);
  a.io(s.position.lat_deg);
  a.io(s.position.lon_deg);
  a.io(s.position.alt_m);
  a.io(s.enu_m);
  a.io(s.true_enu_m);
}
template <typename Archive>
void sample_fields(Archive& a, ImuSample& s) {
  a.io(s.sensor_id);
  a.io(s.stamp);
  a.io(s.accel_mps2);
  a.io(s.gyro_rad_s);
}
template <typename Archive>
void sample_fields(Archive& a, MagnetometerSample& s) {
  a.io(s.sensor_id);
  a.io(s.stamp);
  a.io(s.heading_rad);
  a.io(s.field_ut);
}
template <typename Archive>
void sample_fields(Archive& a, TachometerSample& s) {
  a.io(s.sensor_id);
  a.io(s.stamp);
  a.io(s.wheel_spin_rad_s);
}

#define SYNDDS_SAMPLE_STATE_(TYPE)                                            \
  void save_sample(core::StateWriter& w, const TYPE& s) {                     \
    sample_fields(w, const_cast<TYPE&>(s));                                   \
  }                                                                           \
  void load_sample(core::StateReader& r, TYPE& s) { sample_fields(r, s); }
SYNDDS_SAMPLE_STATE_(GpsSample)
SYNDDS_SAMPLE_STATE_(ImuSample)
SYNDDS_SAMPLE_STATE_(MagnetometerSample)
SYNDDS_SAMPLE_STATE_(TachometerSample)
#undef SYNDDS_SAMPLE_STATE_

// Configuration (rates, noise levels, mounts, the geodetic converter, the magnetometer's
// world field) is rebuilt from the rig; only what the runs changed is written.
void GpsSensor::save_state(core::StateWriter& w) const {
  w.begin("gps", 1);
  save_schedule(w);
  rng_.save_state(w);
  noise_.save_state(w);
  w.end();
}
void GpsSensor::load_state(core::StateReader& r) {
  r.begin("gps", 1);
  load_schedule(r, config_.id);
  rng_.load_state(r);
  noise_.load_state(r);
  r.end();
}

void ImuSensor::save_state(core::StateWriter& w) const {
  w.begin("imu", 1);
  save_schedule(w);
  rng_.save_state(w);
  accel_noise_.save_state(w);
  gyro_noise_.save_state(w);
  w.end();
}
void ImuSensor::load_state(core::StateReader& r) {
  r.begin("imu", 1);
  load_schedule(r, config_.id);
  rng_.load_state(r);
  accel_noise_.load_state(r);
  gyro_noise_.load_state(r);
  r.end();
}

void MagnetometerSensor::save_state(core::StateWriter& w) const {
  w.begin("magnetometer", 1);
  save_schedule(w);
  rng_.save_state(w);
  w.end();
}
void MagnetometerSensor::load_state(core::StateReader& r) {
  r.begin("magnetometer", 1);
  load_schedule(r, config_.id);
  rng_.load_state(r);
  r.end();
}

void TachometerSensor::save_state(core::StateWriter& w) const {
  w.begin("tachometer", 1);
  save_schedule(w);
  rng_.save_state(w);
  w.end();
}
void TachometerSensor::load_state(core::StateReader& r) {
  r.begin("tachometer", 1);
  load_schedule(r, config_.id);
  rng_.load_state(r);
  r.end();
}

}  // namespace syndds::sensors
