#include "convoy/v2v.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numeric>

#include "core/error.hpp"
#include "core/state_io.hpp"

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

namespace {

template <typename Sample>
void save_optional(core::StateWriter& w, const std::optional<Sample>& s) {
  w.io(s.has_value());
  if (s) sensors::save_sample(w, *s);
}

template <typename Sample>
void load_optional(core::StateReader& r, std::optional<Sample>& s) {
  s.reset();
  if (r.get<bool>()) {
    Sample x;
    sensors::load_sample(r, x);
    s = std::move(x);
  }
}

}  // namespace

// Everything but the construction data (config, ids, wheel radius, checked by the reader).
// The messages waiting for their latency are written field by field: a field added to
// proto::V2VMessageMsg must be added here too (frame is set on release, not yet meaningful).
void V2VBroadcaster::save_state(core::StateWriter& w) const {
  w.begin("v2v", 1);
  w.io(vehicle_id_);
  w.io(config_.rate_hz);
  w.io(config_.latency_s);
  w.io(config_.drop_probability);
  rng_.save_state(w);
  save_optional(w, gps_);
  save_optional(w, compass_);
  save_optional(w, tachometer_);
  w.io(sequence_);
  w.io(dropped_);
  w.io(static_cast<std::uint64_t>(pending_.size()));
  for (const auto& [release, m] : pending_) {
    w.io(release);
    w.io(m.vehicle_id);
    w.io(m.source);
    w.io(m.frame);
    w.io(m.sequence);
    w.io(m.sensor_time_s);
    w.io(m.latitude_deg);
    w.io(m.longitude_deg);
    w.io(m.altitude_m);
    w.io(m.speed_mps);
    w.io(m.heading_rad);
  }
  w.end();
}

void V2VBroadcaster::load_state(core::StateReader& r) {
  r.begin("v2v", 1);
  const auto vehicle = r.get<std::string>();
  if (vehicle != vehicle_id_) {
    r.fail("the state is of the V2V broadcaster of vehicle '" + vehicle + "', not '" +
           vehicle_id_ + "'");
  }
  V2VConfig saved;
  r.io(saved.rate_hz);
  r.io(saved.latency_s);
  r.io(saved.drop_probability);
  if (saved.rate_hz != config_.rate_hz || saved.latency_s != config_.latency_s ||
      saved.drop_probability != config_.drop_probability) {
    auto num = [](double v) {  // shortest text that reads back as v
      char buf[32];
      return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
    };
    auto text = [&](const V2VConfig& c) {
      return "rate_hz " + num(c.rate_hz) + ", latency_s " + num(c.latency_s) +
             ", drop_probability " + num(c.drop_probability);
    };
    r.fail("vehicle '" + vehicle_id_ + "': the state's v2v configuration (" + text(saved) +
           ") differs from this one's (" + text(config_) + ")");
  }
  rng_.load_state(r);
  load_optional(r, gps_);
  load_optional(r, compass_);
  load_optional(r, tachometer_);
  r.io(sequence_);
  r.io(dropped_);
  pending_.clear();
  const auto n = r.get<std::uint64_t>();
  for (std::uint64_t k = 0; k < n; ++k) {
    std::pair<double, proto::V2VMessageMsg> p;
    auto& m = p.second;
    r.io(p.first);
    r.io(m.vehicle_id);
    r.io(m.source);
    r.io(m.frame);
    r.io(m.sequence);
    r.io(m.sensor_time_s);
    r.io(m.latitude_deg);
    r.io(m.longitude_deg);
    r.io(m.altitude_m);
    r.io(m.speed_mps);
    r.io(m.heading_rad);
    pending_.push_back(std::move(p));
  }
  r.end();
}

}  // namespace syndds::convoy
