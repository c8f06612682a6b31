#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "sensors/interoceptive.hpp"

using namespace syndds;
using namespace syndds::sensors;

namespace {
constexpr double kStep = 0.002;

vehicle::VehicleSnapshot at_rest(double t) {
  vehicle::VehicleSnapshot s;
  s.time_s = t;
  s.wheels.resize(4);
  return s;
}

struct Stats {
  double mean = 0.0, std = 0.0;
};
Stats stats(const std::vector<double>& v) {
  Stats s;
  for (double x : v) s.mean += x;
  s.mean /= static_cast<double>(v.size());
  for (double x : v) s.std += (x - s.mean) * (x - s.mean);
  s.std = std::sqrt(s.std / static_cast<double>(v.size() - 1));
  return s;
}

template <typename Sensor, typename Sample>
std::vector<Sample> run_collect(Sensor& sensor, double seconds,
                                const std::function<vehicle::VehicleSnapshot(double)>& state) {
  std::vector<Sample> out;
  const auto steps = static_cast<std::int64_t>(std::llround(seconds / kStep));
  for (std::int64_t i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) * kStep;
    sensor.update(state(t));
    for (auto& s : sensor.take_available(t)) out.push_back(std::move(s));
  }
  return out;
}
}  // namespace

TEST(Imu, AtRestReadsGravityUpAndZeroRate) {
  ImuConfig cfg;
  cfg.mount.pose.position = Vec3(0.5, 0.3, 1.0);  // lever arm changes nothing at rest
  ImuSensor imu(cfg, 7, kStep);
  const auto samples = run_collect<ImuSensor, ImuSample>(imu, 1.0, at_rest);
  ASSERT_EQ(samples.size(), 101u);
  for (const auto& s : samples) {
    EXPECT_NEAR(s.accel_mps2.z(), 9.80665, 1e-12);
    EXPECT_NEAR(s.accel_mps2.head<2>().norm(), 0.0, 1e-12);
    EXPECT_NEAR(s.gyro_rad_s.norm(), 0.0, 1e-12);
  }
}

TEST(Imu, TiltedAndTurningVehicleReadsRotatedGravityAndBodyRate) {
  ImuConfig cfg;
  ImuSensor imu(cfg, 7, kStep);
  const double pitch = deg_to_rad(10.0);  // nose down (positive pitch about y)
  const auto samples = run_collect<ImuSensor, ImuSample>(imu, 0.1, [&](double t) {
    auto s = at_rest(t);
    s.pose.orientation =
        Quat(Eigen::AngleAxisd(0.7, Vec3::UnitZ())) * Quat(Eigen::AngleAxisd(pitch, Vec3::UnitY()));
    s.angular_velocity = Vec3(0, 0, 0.25);  // yaw rate, world frame
    return s;
  });
  ASSERT_FALSE(samples.empty());
  const auto& m = samples.back();
  // Gravity reaction g*z_world expressed in the pitched body frame: (-g sin p, 0, g cos p).
  EXPECT_NEAR(m.accel_mps2.x(), -kGravity * std::sin(pitch), 1e-9);
  EXPECT_NEAR(m.accel_mps2.z(), kGravity * std::cos(pitch), 1e-9);
  EXPECT_NEAR(m.gyro_rad_s.x(), -0.25 * std::sin(pitch), 1e-12);
  EXPECT_NEAR(m.gyro_rad_s.z(), 0.25 * std::cos(pitch), 1e-12);
}

TEST(Imu, CentripetalAccelerationAtALeverArm) {
  ImuConfig cfg;
  cfg.mount.pose.position = Vec3(2.0, 0.0, 0.0);
  ImuSensor imu(cfg, 1, kStep);
  const double w = 0.5;
  const auto samples = run_collect<ImuSensor, ImuSample>(imu, 0.02, [&](double t) {
    auto s = at_rest(t);
    s.angular_velocity = Vec3(0, 0, w);
    return s;
  });
  ASSERT_FALSE(samples.empty());
  EXPECT_NEAR(samples.back().accel_mps2.x(), -w * w * 2.0, 1e-12);  // towards the axis
}

// Noise: 10^4 samples, std within 5 % of the configured values (ADIS16448-class numbers,
// docs/sources.md: discrete std = density * sqrt(rate)).
TEST(Imu, WhiteNoiseStdMatchesConfiguration) {
  ImuConfig cfg;
  cfg.rate_hz = 500.0;
  cfg.accelerometer.white_std = Vec3::Constant(4e-3 * std::sqrt(cfg.rate_hz));
  cfg.gyroscope.white_std = Vec3::Constant(3.4e-4 * std::sqrt(cfg.rate_hz));
  ImuSensor imu(cfg, derive_seed(42, "lead/imu"), kStep);
  const auto samples = run_collect<ImuSensor, ImuSample>(imu, 20.0 - kStep, at_rest);
  ASSERT_EQ(samples.size(), 10000u);
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> a, g;
    for (const auto& s : samples) {
      a.push_back(s.accel_mps2[axis] - (axis == 2 ? kGravity : 0.0));
      g.push_back(s.gyro_rad_s[axis]);
    }
    const Stats sa = stats(a), sg = stats(g);
    EXPECT_NEAR(sa.std, cfg.accelerometer.white_std[axis],
                0.05 * cfg.accelerometer.white_std[axis]);
    EXPECT_NEAR(sg.std, cfg.gyroscope.white_std[axis], 0.05 * cfg.gyroscope.white_std[axis]);
    // Mean within 4 standard errors of zero.
    EXPECT_LT(std::abs(sa.mean), 4.0 * sa.std / 100.0);
    EXPECT_LT(std::abs(sg.mean), 4.0 * sg.std / 100.0);
  }
}

TEST(Imu, BiasRandomWalkIncrementsMatchDensity) {
  ImuConfig cfg;
  cfg.rate_hz = 100.0;
  cfg.gyroscope.walk_per_sqrt_s = Vec3::Constant(1e-3);  // rad/s / sqrt(s)
  ImuSensor imu(cfg, 99, kStep);
  const auto samples = run_collect<ImuSensor, ImuSample>(imu, 100.0, at_rest);
  ASSERT_EQ(samples.size(), 10001u);
  std::vector<double> inc;
  for (std::size_t i = 1; i < samples.size(); ++i) {
    inc.push_back(samples[i].gyro_rad_s.x() - samples[i - 1].gyro_rad_s.x());
  }
  const double expected = 1e-3 * std::sqrt(0.01);
  EXPECT_NEAR(stats(inc).std, expected, 0.05 * expected);
}

TEST(Gps, NoiselessSphereGpsMatchesOracleAndMount) {
  GpsConfig cfg;
  cfg.model = GeodeticModel::sphere;
  cfg.mount.pose.position = Vec3(1.0, 0.0, 0.0);  // antenna 1 m ahead of the reference
  GpsSensor gps(cfg, kDefaultOrigin, 1, kStep);
  const auto samples = run_collect<GpsSensor, GpsSample>(gps, 0.2, [](double t) {
    auto s = at_rest(t);
    s.pose.position = Vec3(100.0, 101.0, 0.0);
    s.pose.orientation = quat_from_yaw(-std::numbers::pi / 2.0);  // facing south
    return s;
  });
  ASSERT_EQ(samples.size(), 2u);  // t = 0 and 0.1 (the 0.2 one is available at 0.3)
  EXPECT_NEAR(samples[0].position.lat_deg, 43.070899322, 1e-8);
  EXPECT_NEAR(samples[0].position.lon_deg, -89.398768911, 1e-8);
  EXPECT_NEAR((samples[0].enu_m - Vec3(100, 100, 0)).norm(), 0.0, 1e-9);
}

TEST(Gps, NoiseStdAndWalkMatchConfiguration) {
  GpsConfig cfg;
  cfg.rate_hz = 100.0;
  cfg.lag_s = 0.0;
  cfg.noise.white_std = Vec3(0.5, 0.8, 1.5);
  GpsSensor gps(cfg, kDefaultOrigin, derive_seed(42, "lead/gps"), kStep);
  const auto samples = run_collect<GpsSensor, GpsSample>(gps, 100.0 - 0.01, at_rest);
  ASSERT_EQ(samples.size(), 10000u);
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> v;
    for (const auto& s : samples) v.push_back(s.enu_m[axis]);
    EXPECT_NEAR(stats(v).std, cfg.noise.white_std[axis], 0.05 * cfg.noise.white_std[axis]);
  }
  // Geodetic output is the conversion of the noisy ENU position.
  const auto& s = samples[17];
  EXPECT_LT((gps.converter().to_enu(s.position) - s.enu_m).norm(), 1e-6);
}

TEST(Magnetometer, HeadingNoiseAndField) {
  MagnetometerConfig cfg;
  cfg.rate_hz = 100.0;
  cfg.heading_noise_std_rad = 0.02;
  MagnetometerSensor mag(cfg, 5, kStep);
  const double yaw = deg_to_rad(30.0);  // ENU yaw 30 deg: compass heading 60 deg
  const auto samples =
      run_collect<MagnetometerSensor, MagnetometerSample>(mag, 100.0 - 0.01, [&](double t) {
        auto s = at_rest(t);
        s.pose.orientation = quat_from_yaw(yaw);
        return s;
      });
  ASSERT_EQ(samples.size(), 10000u);
  std::vector<double> h;
  for (const auto& s : samples) h.push_back(s.heading_rad);
  const Stats st = stats(h);
  EXPECT_NEAR(st.mean, deg_to_rad(60.0), 4.0 * 0.02 / 100.0);
  EXPECT_NEAR(st.std, 0.02, 0.05 * 0.02);
  // Noiseless field: horizontal component points to magnetic north in the body frame.
  const Vec3 f = samples[0].field_ut;
  EXPECT_NEAR(f.norm(), 50.0, 1e-9);
  EXPECT_NEAR(std::atan2(-f.y(), f.x()), -deg_to_rad(60.0), 1e-9);  // north is 60 deg to the left
}

TEST(Tachometer, SpinRatesWithNoise) {
  TachometerConfig cfg;
  cfg.noise_std_rad_s = 0.1;
  TachometerSensor tach(cfg, 11, kStep);
  const auto samples =
      run_collect<TachometerSensor, TachometerSample>(tach, 100.0 - 0.01, [](double t) {
        auto s = at_rest(t);
        for (std::size_t i = 0; i < 4; ++i) s.wheels[i].spin_rad_s = 10.0 + static_cast<double>(i);
        return s;
      });
  ASSERT_EQ(samples.size(), 10000u);
  for (std::size_t w = 0; w < 4; ++w) {
    std::vector<double> v;
    for (const auto& s : samples) v.push_back(s.wheel_spin_rad_s[w]);
    const Stats st = stats(v);
    EXPECT_NEAR(st.mean, 10.0 + static_cast<double>(w), 4.0 * 0.1 / 100.0);
    EXPECT_NEAR(st.std, 0.1, 0.005);
  }
}

// Rate and lag to the frame: GPS 10 Hz lag 0.1 s fed every 2 ms step; frames of 10 ms.
TEST(Timing, GpsRateAndLagHonouredExactly) {
  GpsConfig cfg;  // 10 Hz, lag 0.1 s
  GpsSensor gps(cfg, kDefaultOrigin, 3, kStep);
  std::vector<std::pair<double, GpsSample>> seen;  // (time it came out, sample)
  for (std::int64_t i = 0; i <= 1000; ++i) {
    const double t = static_cast<double>(i) * kStep;
    auto s = at_rest(t);
    s.pose.position = Vec3(t, 0, 0);  // position encodes the sampling time
    gps.update(s);
    for (auto& g : gps.take_available(t)) seen.emplace_back(t, std::move(g));
  }
  ASSERT_EQ(seen.size(), 20u);  // measured at 0.0 .. 1.9, released at 0.1 .. 2.0
  for (std::size_t k = 0; k < seen.size(); ++k) {
    const auto& [out_time, g] = seen[k];
    EXPECT_EQ(g.stamp.sequence, k);
    EXPECT_NEAR(g.stamp.time_s, 0.1 * static_cast<double>(k), 1e-12);
    EXPECT_NEAR(g.stamp.available_s, g.stamp.time_s + 0.1, 1e-12);
    EXPECT_NEAR(out_time, g.stamp.available_s, 1e-12);     // released at that step, not later
    EXPECT_NEAR(g.true_enu_m.x(), g.stamp.time_s, 1e-12);  // measured the state at time_s
  }
}

TEST(Timing, FractionalPeriodsAverageToTheRateOnTheFrameGrid) {
  // 30 Hz camera fed per 10 ms frame: measurement k at frame ceil(k * 10/3).
  SampleClock clock(30.0, 0.05, 0.01, "camera");
  EXPECT_EQ(clock.lag_ticks(), 5);
  std::vector<std::int64_t> ticks;
  for (std::int64_t f = 0; f < 300; ++f) {
    if (auto k = clock.trigger(f)) {
      EXPECT_EQ(*k, ticks.size());
      ticks.push_back(f);
    }
  }
  ASSERT_EQ(ticks.size(), 90u);  // exactly 30 per simulated second
  EXPECT_EQ(std::vector<std::int64_t>(ticks.begin(), ticks.begin() + 7),
            (std::vector<std::int64_t>{0, 4, 7, 10, 14, 17, 20}));
  for (std::size_t k = 0; k < ticks.size(); ++k) {
    // Never early, never more than one frame late.
    const double ideal = static_cast<double>(k) / 30.0;
    EXPECT_GE(clock.time_of(ticks[k]) + 1e-12, ideal);
    EXPECT_LT(clock.time_of(ticks[k]) - ideal, 0.01);
  }
  // A lag that is not a whole number of ticks rounds up; rates above the feed rate are errors.
  EXPECT_EQ(SampleClock(10.0, 0.015, 0.01, "x").lag_ticks(), 2);
  EXPECT_THROW(SampleClock(200.0, 0.0, 0.01, "x"), std::invalid_argument);
}

TEST(Timing, LateStartBeginsAtTheNextDueMeasurement) {
  SampleClock clock(10.0, 0.1, 0.002, "gps");
  EXPECT_FALSE(clock.trigger(501).has_value());  // joined at 1.002 s
  std::optional<std::uint64_t> k;
  std::int64_t t = 502;
  for (; !(k = clock.trigger(t)); ++t) {
  }
  EXPECT_EQ(t, 550);
  EXPECT_EQ(*k, 11u);
}

TEST(Seeds, StreamsAreReproducibleAndIndependent) {
  EXPECT_EQ(derive_seed(42, "lead/imu"), derive_seed(42, "lead/imu"));
  EXPECT_NE(derive_seed(42, "lead/imu"), derive_seed(42, "lead/gps"));
  EXPECT_NE(derive_seed(42, "lead/imu"), derive_seed(43, "lead/imu"));
  ImuConfig cfg;
  cfg.accelerometer.white_std = Vec3::Constant(0.1);
  ImuSensor a(cfg, derive_seed(42, "lead/imu"), kStep), b(cfg, derive_seed(42, "lead/imu"), kStep);
  const auto sa = run_collect<ImuSensor, ImuSample>(a, 0.5, at_rest);
  const auto sb = run_collect<ImuSensor, ImuSample>(b, 0.5, at_rest);
  ASSERT_EQ(sa.size(), sb.size());
  for (std::size_t i = 0; i < sa.size(); ++i) EXPECT_EQ(sa[i].accel_mps2, sb[i].accel_mps2);
}

TEST(Seeds, NormalTableHasUnitVariance) {
  const auto& t = NormalTable::instance();
  double s = 0.0, s2 = 0.0;
  for (std::uint32_t i = 0; i < 65536; ++i) {
    s += t(i);
    s2 += static_cast<double>(t(i)) * t(i);
  }
  EXPECT_NEAR(s / 65536.0, 0.0, 1e-6);
  EXPECT_NEAR(s2 / 65536.0, 1.0, 1e-5);
  EXPECT_NEAR(inverse_normal_cdf(0.975), 1.959963985, 1e-8);
}
