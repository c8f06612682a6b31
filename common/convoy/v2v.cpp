#include "convoy/v2v.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "core/error.hpp"

namespace syndds::convoy {

double tachometer_speed(const std::vector<double>& wheel_spin_rad_s, double wheel_radius_m) {
  if (wheel_spin_rad_s.empty()) return 0.0;
  const double sum = std::accumulate(wheel_spin_rad_s.begin(), wheel_spin_rad_s.end(), 0.0);
  return sum / static_cast<double>(wheel_spin_rad_s.size()) * wheel_radius_m;
}

V2VBroadcaster::V2VBroadcaster(V2VConfig config, std::string vehicle_id, std::string source,
                               double wheel_radius_m, std::uint64_t scenario_seed)
    : config_(config),
      vehicle_id_(std::move(vehicle_id)),
      source_(std::move(source)),
      wheel_radius_m_(wheel_radius_m),
      rng_(sensors::derive_seed(scenario_seed, vehicle_id_ + "/v2v")) {
  if (!(config_.rate_hz > 0.0) || !std::isfinite(config_.rate_hz)) {
    throw ConfigError("v2v.rate_hz must be a positive number");
  }
  if (!(config_.latency_s >= 0.0) || !std::isfinite(config_.latency_s)) {
    throw ConfigError("v2v.latency_s must be >= 0");
  }
  if (!(config_.drop_probability >= 0.0 && config_.drop_probability <= 1.0)) {
    throw ConfigError("v2v.drop_probability must be in [0, 1]");
  }
}

void V2VBroadcaster::observe(const sensors::InteroceptiveBatch& batch) {
  if (!batch.gps.empty()) gps_ = batch.gps.back();
  if (!batch.magnetometer.empty()) compass_ = batch.magnetometer.back();
  if (!batch.tachometer.empty()) tachometer_ = batch.tachometer.back();
}

std::vector<proto::V2VMessageMsg> V2VBroadcaster::step(std::int64_t frame, double time_s) {
  // Build every message due by now (at most one per frame at the usual rates), from the newest
  // readings; a vehicle without a fix yet has nothing to say.
  const double period = 1.0 / config_.rate_hz;
  constexpr double kEps = 1e-9;
  while (static_cast<double>(sequence_) * period <= time_s + kEps) {
    const std::uint64_t number = sequence_++;
    if (!gps_ || !compass_ || !tachometer_) continue;
    // One draw per message built, so the drop pattern does not depend on anything else.
    const bool drop = rng_.uniform() < config_.drop_probability;
    if (drop) {
      ++dropped_;
      continue;
    }
    proto::V2VMessageMsg m;
    m.vehicle_id = vehicle_id_;
    m.source = source_;
    m.sequence = number;
    m.sensor_time_s = gps_->stamp.time_s;  // the position's time: what a receiver projects from
    m.latitude_deg = gps_->position.lat_deg;
    m.longitude_deg = gps_->position.lon_deg;
    m.altitude_m = gps_->position.alt_m;
    m.speed_mps = tachometer_speed(tachometer_->wheel_spin_rad_s, wheel_radius_m_);
    m.heading_rad = compass_->heading_rad;
    pending_.emplace_back(time_s + config_.latency_s, std::move(m));
  }
  std::vector<proto::V2VMessageMsg> out;
  while (!pending_.empty() && pending_.front().first <= time_s + kEps) {
    out.push_back(std::move(pending_.front().second));
    out.back().frame = frame;
    pending_.pop_front();
  }
  return out;
}

}  // namespace syndds::convoy
