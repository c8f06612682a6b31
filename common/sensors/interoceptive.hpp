#pragma once
// Interoceptive sensors fed with the vehicle state every dynamics step: GPS, IMU
// (accelerometer + gyroscope), magnetometer / compass, wheel tachometer.
//
// Each sensor measures at its rate on the tick grid it is fed at (see timing.hpp), adds its
// noise from its own seeded stream, and holds the sample until its available time
// (measurement time + lag). Usage per dynamics step:
//
//   gps.update(snapshot);                      // snapshot.time_s on the step grid
//   for (auto& s : gps.take_available(now_s)) publish(s);
#include <cstdint>
#include <string>
#include <vector>

#include "core/math.hpp"
#include "sensors/geodesy.hpp"
#include "sensors/random.hpp"
#include "sensors/sensor_config.hpp"
#include "sensors/timing.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::sensors {

class NoiseModel3 {
 public:
  explicit NoiseModel3(const NoiseConfig& config) : config_(config), bias_(config.initial_bias) {}
  /// Advances the bias by dt and returns truth + bias + white noise.
  Vec3 apply(const Vec3& truth, double dt, NormalRng& rng);
  const Vec3& bias() const { return bias_; }
  /// Checkpoint state: the bias random walk.
  void save_state(core::StateWriter& w) const { w.io(bias_); }
  void load_state(core::StateReader& r) { r.io(bias_); }

 private:
  NoiseConfig config_;
  Vec3 bias_;
};

struct GpsSample {
  std::string sensor_id;
  SampleStamp stamp;
  Geodetic position;               // noisy
  Vec3 enu_m = Vec3::Zero();       // noisy local position
  Vec3 true_enu_m = Vec3::Zero();  // ground truth (for recording, not for controllers)
};

struct ImuSample {
  std::string sensor_id;
  SampleStamp stamp;
  Vec3 accel_mps2 = Vec3::Zero();  // specific force in the sensor frame (rest: +g up)
  Vec3 gyro_rad_s = Vec3::Zero();  // angular velocity in the sensor frame
};

struct MagnetometerSample {
  std::string sensor_id;
  SampleStamp stamp;
  double heading_rad = 0.0;      // compass heading of the sensor x axis, clockwise
                                 // from true north, [0, 2 pi)
  Vec3 field_ut = Vec3::Zero();  // magnetic field in the sensor frame
};

struct TachometerSample {
  std::string sensor_id;
  SampleStamp stamp;
  std::vector<double> wheel_spin_rad_s;  // in the snapshot's wheel order (FL, FR, RL, RR)
};

/// Exact encodings of the samples (for the lag queues and V2V in checkpoints).
void save_sample(core::StateWriter& w, const GpsSample& s);
void save_sample(core::StateWriter& w, const ImuSample& s);
void save_sample(core::StateWriter& w, const MagnetometerSample& s);
void save_sample(core::StateWriter& w, const TachometerSample& s);
void load_sample(core::StateReader& r, GpsSample& s);
void load_sample(core::StateReader& r, ImuSample& s);
void load_sample(core::StateReader& r, MagnetometerSample& s);
void load_sample(core::StateReader& r, TachometerSample& s);

/// Common scheduling of the sensors below (rate, lag, queue).
template <typename Sample>
class PeriodicSensor {
 public:
  std::vector<Sample> take_available(double now_s) {
    return queue_.take_ready(clock_.tick_of(now_s));
  }
  const SampleClock& clock() const { return clock_; }
  std::size_t pending() const { return queue_.pending(); }

 protected:
  /// Checkpoint state of the schedule: clock, samples waiting for their lag, last tick
  /// measured (the next measurement's dt, hence its bias walk, depends on it).
  void save_schedule(core::StateWriter& w) const {
    clock_.save_state(w);
    queue_.save_state(w, [](core::StateWriter& ww, const Sample& s) { save_sample(ww, s); });
    w.io(last_tick_);
    w.io(has_last_);
  }
  void load_schedule(core::StateReader& r, const std::string& id) {
    clock_.load_state(r, id);
    queue_.load_state(r, [](core::StateReader& rr, Sample& s) { load_sample(rr, s); });
    r.io(last_tick_);
    r.io(has_last_);
  }

  PeriodicSensor(double rate_hz, double lag_s, double tick_s, const std::string& id)
      : clock_(rate_hz, lag_s, tick_s, id) {}
  template <typename Measure>
  void tick(double time_s, Measure&& measure) {
    const std::int64_t t = clock_.tick_of(time_s);
    if (const auto k = clock_.trigger(t)) {
      const double dt = has_last_ ? clock_.time_of(t - last_tick_) : 0.0;
      Sample sample = measure(dt);
      sample.stamp = clock_.stamp(*k, t);
      queue_.push(std::move(sample), t + clock_.lag_ticks());
      last_tick_ = t;
      has_last_ = true;
    }
  }

 private:
  SampleClock clock_;
  LagQueue<Sample> queue_;
  std::int64_t last_tick_ = 0;
  bool has_last_ = false;
};

class GpsSensor : public PeriodicSensor<GpsSample> {
 public:
  /// `tick_s`: the interval update() is called at (the dynamics step).
  GpsSensor(const GpsConfig& config, const Geodetic& origin, std::uint64_t seed, double tick_s);
  void update(const vehicle::VehicleSnapshot& state);
  const GpsConfig& config() const { return config_; }
  const GeodeticConverter& converter() const { return converter_; }
  /// Checkpoint state: schedule, random stream, bias walk (docs/sensors.md).
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  GpsConfig config_;
  GeodeticConverter converter_;
  NormalRng rng_;
  NoiseModel3 noise_;
};

class ImuSensor : public PeriodicSensor<ImuSample> {
 public:
  ImuSensor(const ImuConfig& config, std::uint64_t seed, double tick_s);
  void update(const vehicle::VehicleSnapshot& state);
  const ImuConfig& config() const { return config_; }
  /// Checkpoint state: schedule, random stream, both bias walks.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  ImuConfig config_;
  NormalRng rng_;
  NoiseModel3 accel_noise_;
  NoiseModel3 gyro_noise_;
};

class MagnetometerSensor : public PeriodicSensor<MagnetometerSample> {
 public:
  MagnetometerSensor(const MagnetometerConfig& config, std::uint64_t seed, double tick_s);
  void update(const vehicle::VehicleSnapshot& state);
  const MagnetometerConfig& config() const { return config_; }
  /// Checkpoint state: schedule and random stream.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);
  /// Earth's field in the world (ENU) frame.
  Vec3 world_field_ut() const { return world_field_; }

 private:
  MagnetometerConfig config_;
  NormalRng rng_;
  Vec3 world_field_;
};

class TachometerSensor : public PeriodicSensor<TachometerSample> {
 public:
  TachometerSensor(const TachometerConfig& config, std::uint64_t seed, double tick_s);
  void update(const vehicle::VehicleSnapshot& state);
  const TachometerConfig& config() const { return config_; }
  /// Checkpoint state: schedule and random stream.
  void save_state(core::StateWriter& w) const;
  void load_state(core::StateReader& r);

 private:
  TachometerConfig config_;
  NormalRng rng_;
};

/// Compass heading (clockwise from north, [0, 2 pi)) of an orientation's x axis.
double compass_heading(const Quat& orientation);

}  // namespace syndds::sensors
