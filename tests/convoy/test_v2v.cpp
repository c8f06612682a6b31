// V2V broadcasts: rate, latency in frames, seeded drops, content from the sensor readings.
#include <gtest/gtest.h>

#include <cmath>

#include "convoy/v2v.hpp"

using namespace syndds;
using namespace syndds::convoy;

namespace {

constexpr double kHeartbeat = 0.01;

// A batch with one reading of each kind, as measured at `t`.
sensors::InteroceptiveBatch readings(double t, double lat, double spin) {
  sensors::InteroceptiveBatch b;
  sensors::GpsSample g;
  g.stamp.time_s = t;
  g.position = {lat, -89.4, 260.0};
  b.gps.push_back(g);
  sensors::MagnetometerSample m;
  m.stamp.time_s = t;
  m.heading_rad = 1.0;
  b.magnetometer.push_back(m);
  sensors::TachometerSample s;
  s.stamp.time_s = t;
  s.wheel_spin_rad_s = {spin, spin, spin + 1.0, spin - 1.0};
  b.tachometer.push_back(s);
  return b;
}

// Runs `frames` frames; returns every message with the frame it was published in.
std::vector<proto::V2VMessageMsg> run(V2VBroadcaster& b, int frames) {
  std::vector<proto::V2VMessageMsg> out;
  for (int k = 0; k <= frames; ++k) {
    const double t = k * kHeartbeat;
    b.observe(readings(t, 43.0 + t * 1e-6, 10.0));
    for (auto& m : b.step(k, t)) out.push_back(m);
  }
  return out;
}

}  // namespace

TEST(V2V, SendsAtItsRateFromTheNewestReadings) {
  V2VBroadcaster b({10.0, 0.0, 0.0}, "l1", "vehicle/l1", 0.5, 7);
  const auto msgs = run(b, 1000);  // 10 s
  ASSERT_EQ(msgs.size(), 101u);     // t = 0, 0.1, ..., 10.0
  for (std::size_t i = 0; i < msgs.size(); ++i) {
    EXPECT_EQ(msgs[i].sequence, i);
    EXPECT_EQ(msgs[i].frame, static_cast<std::int64_t>(i * 10));
    EXPECT_EQ(msgs[i].vehicle_id, "l1");
    EXPECT_DOUBLE_EQ(msgs[i].sensor_time_s, msgs[i].frame * kHeartbeat);
    EXPECT_DOUBLE_EQ(msgs[i].speed_mps, 10.0 * 0.5);  // mean wheel spin * radius
    EXPECT_DOUBLE_EQ(msgs[i].heading_rad, 1.0);
  }
}

TEST(V2V, LatencyDelaysPublicationByWholeFrames) {
  V2VBroadcaster b({5.0, 0.25, 0.0}, "l1", "vehicle/l1", 0.5, 7);
  const auto msgs = run(b, 300);
  ASSERT_FALSE(msgs.empty());
  for (const auto& m : msgs) {
    // Built at sequence / rate, published 0.25 s (25 frames) later.
    EXPECT_EQ(m.frame, static_cast<std::int64_t>(m.sequence) * 20 + 25);
  }
  EXPECT_EQ(msgs.back().frame, 285);  // the one built at frame 280 is due at 305
}

TEST(V2V, DropsTheConfiguredShareReproducibly) {
  V2VBroadcaster a({100.0, 0.0, 0.2}, "l1", "vehicle/l1", 0.5, 7);
  V2VBroadcaster b({100.0, 0.0, 0.2}, "l1", "vehicle/l1", 0.5, 7);
  V2VBroadcaster other_seed({100.0, 0.0, 0.2}, "l1", "vehicle/l1", 0.5, 8);
  const auto ma = run(a, 20000);
  const auto mb = run(b, 20000);
  const auto mc = run(other_seed, 20000);
  const double built = static_cast<double>(a.built());
  ASSERT_EQ(built, 20001.0);
  // Binomial: std of the share is sqrt(0.2 * 0.8 / n) = 0.0028; allow 4 of them.
  EXPECT_NEAR(static_cast<double>(a.dropped()) / built, 0.2, 4 * std::sqrt(0.16 / built));
  EXPECT_EQ(ma.size() + a.dropped(), a.built());
  ASSERT_EQ(ma.size(), mb.size());
  for (std::size_t i = 0; i < ma.size(); ++i) EXPECT_EQ(ma[i].sequence, mb[i].sequence);
  bool differs = ma.size() != mc.size();
  for (std::size_t i = 0; !differs && i < ma.size(); ++i) differs = ma[i].sequence != mc[i].sequence;
  EXPECT_TRUE(differs) << "another seed must drop other messages";
}

TEST(V2V, CutLinkSendsNothingAndNothingBeforeTheFirstFix) {
  V2VBroadcaster cut({10.0, 0.0, 1.0}, "l1", "vehicle/l1", 0.5, 7);
  EXPECT_TRUE(run(cut, 500).empty());
  V2VBroadcaster b({10.0, 0.0, 0.0}, "l1", "vehicle/l1", 0.5, 7);
  EXPECT_TRUE(b.step(0, 0.0).empty());  // no readings yet
}

TEST(V2V, RejectsImpossibleSettings) {
  EXPECT_THROW(V2VBroadcaster({0.0, 0.0, 0.0}, "l1", "s", 0.5, 1), std::exception);
  EXPECT_THROW(V2VBroadcaster({10.0, -1.0, 0.0}, "l1", "s", 0.5, 1), std::exception);
  EXPECT_THROW(V2VBroadcaster({10.0, 0.0, 1.5}, "l1", "s", 0.5, 1), std::exception);
}
