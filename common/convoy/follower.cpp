#include "convoy/follower.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numbers>
#include <sstream>

#include "convoy/v2v.hpp"

namespace syndds::convoy {
namespace {

Vec2 direction(double yaw) { return Vec2(std::cos(yaw), std::sin(yaw)); }

double wrap_angle(double a) {
  a = std::fmod(a + std::numbers::pi, 2.0 * std::numbers::pi);
  if (a < 0.0) a += 2.0 * std::numbers::pi;
  return a - std::numbers::pi;
}

}  // namespace

double yaw_from_heading(double heading_rad) {
  return wrap_angle(std::numbers::pi / 2.0 - heading_rad);
}

ConvoyFollower::ConvoyFollower(FollowerConfig config, FollowerVehicle vehicle,
                               sensors::GeodeticConverter converter)
    : config_(std::move(config)),
      vehicle_(vehicle),
      converter_(converter),
      speed_pid_(config_.speed_pid, 5.0) {}

void ConvoyFollower::update_own(double time_s, double dt, const OwnReadings& own) {
  if (!own.compass.empty()) yaw_reading_ = yaw_from_heading(own.compass.back().heading_rad);
  if (!own.wheel_speeds.empty()) {
    speed_reading_ = tachometer_speed(own.wheel_speeds.back().wheel_spin_rad_s,
                                      vehicle_.wheel_radius_m);
  }
  if (own_) {
    own_->position += own_->speed * dt * direction(own_->yaw);  // dead reckoning
    if (yaw_reading_) own_->yaw = *yaw_reading_;
    own_->speed = speed_reading_;
  }
  for (const auto& fix : own.gps) {
    if (!yaw_reading_) continue;  // a fix is only useful with a heading to project it along
    const Vec3 enu = converter_.to_enu({fix.latitude_deg, fix.longitude_deg, fix.altitude_m});
    const double age = std::max(0.0, time_s - fix.stamp.time_s);
    const Vec2 now = Vec2(enu.x(), enu.y()) + speed_reading_ * age * direction(*yaw_reading_);
    if (!own_) {
      own_ = Estimate{now, *yaw_reading_, speed_reading_};
    } else {
      own_->position += config_.fix_gain * (now - own_->position);
    }
  }
}

void ConvoyFollower::update_leader(double time_s, double dt,
                                   const std::vector<proto::V2VMessageMsg>& msgs) {
  if (leader_) leader_->position += leader_->speed * dt * direction(leader_->yaw);
  for (const auto& m : msgs) {
    if (m.vehicle_id != config_.leader) continue;
    // A message older than one already used (reordered, replayed) tells nothing new.
    if (has_leader_sequence_ && m.sequence <= leader_sequence_) continue;
    leader_sequence_ = m.sequence;
    has_leader_sequence_ = true;
    leader_seen_s_ = std::max(leader_seen_s_, m.sensor_time_s);
    const Vec3 enu = converter_.to_enu({m.latitude_deg, m.longitude_deg, m.altitude_m});
    const double yaw = yaw_from_heading(m.heading_rad);
    const double age = std::max(0.0, time_s - m.sensor_time_s);
    const Vec2 now = Vec2(enu.x(), enu.y()) + m.speed_mps * age * direction(yaw);
    if (!leader_) {
      leader_ = Estimate{now, yaw, m.speed_mps};
    } else {
      leader_->position += config_.leader_fix_gain * (now - leader_->position);
      leader_->yaw = yaw;
      leader_->speed = m.speed_mps;
    }
  }
}

void ConvoyFollower::extend_trail() {
  if (!leader_) return;
  if (trail_.empty()) {
    // The trail starts where the follower stands: the stretch to the leader's first reported
    // position is the one part it has not seen the leader drive.
    trail_.push_back(own_->position);
    trail_s_.push_back(0.0);
  }
  const double d = (leader_->position - trail_.back()).norm();
  if (d >= config_.crumb_spacing_m) {
    trail_.push_back(leader_->position);
    trail_s_.push_back(trail_s_.back() + d);
  }
}

double ConvoyFollower::project_on_trail(const Vec2& p) {
  // Search forward from the last segment (a few metres of slack behind): progress is monotone,
  // so a trail that loops back near itself is never taken by its later part too early.
  double best_d2 = std::numeric_limits<double>::infinity();
  double best_s = trail_s_.empty() ? 0.0 : trail_s_[trail_index_];
  std::size_t best_i = trail_index_;
  for (std::size_t i = trail_index_; i + 1 < trail_.size(); ++i) {
    const Vec2 a = trail_[i];
    const Vec2 ab = trail_[i + 1] - a;
    const double len2 = ab.squaredNorm();
    const double u = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const double d2 = (a + u * ab - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best_i = i;
      best_s = trail_s_[i] + u * std::sqrt(len2);
    }
    if (trail_s_[i] > best_s + 30.0) break;  // far enough past the best: stop looking
  }
  trail_index_ = best_i;
  return best_s;
}

Vec2 ConvoyFollower::trail_point(double s) const {
  if (s >= trail_length()) {
    // Past the newest crumb: towards the leader's estimated position.
    const Vec2 last = trail_.back();
    const Vec2 to_leader = leader_->position - last;
    const double rest = to_leader.norm();
    if (rest < 1e-9) return last;
    return last + std::min(1.0, (s - trail_length()) / rest) * to_leader;
  }
  const auto it = std::upper_bound(trail_s_.begin(), trail_s_.end(), s);
  const std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - trail_s_.begin() - 1, 0));
  const double len = trail_s_[i + 1] - trail_s_[i];
  const double u = len > 0.0 ? (s - trail_s_[i]) / len : 0.0;
  return trail_[i] + u * (trail_[i + 1] - trail_[i]);
}

vehicle::DriverInputs ConvoyFollower::update(double time_s, double dt, const OwnReadings& own,
                                             const std::vector<proto::V2VMessageMsg>& leader,
                                             std::vector<FollowerEvent>& events) {
  update_own(time_s, dt, own);
  update_leader(time_s, dt, leader);
  vehicle::DriverInputs hold;
  hold.braking = 1.0;
  if (!own_) return hold;  // no fix or heading yet: stay put

  // Leader lost / found, by the measurement time of its newest message.
  const double silence = leader_seen_s_ < 0.0 ? time_s : time_s - leader_seen_s_;
  if (!lost_ && silence > config_.leader_lost_after_s) {
    lost_ = true;
    std::ostringstream detail;
    detail << "no v2v message from " << config_.leader << " for " << std::fixed
           << std::setprecision(2) << silence << " s";
    events.push_back({"leader_lost", detail.str()});
  } else if (lost_ && silence <= config_.leader_lost_after_s) {
    lost_ = false;
    events.push_back({"leader_found", "v2v messages from " + config_.leader + " again"});
  }
  if (!leader_) return hold;
  extend_trail();

  // Steering: pure pursuit on the trail.
  const double s_here = project_on_trail(own_->position);
  const double lookahead =
      std::max(config_.lookahead_min_m, config_.lookahead_time_s * own_->speed);
  const Vec2 target = trail_point(s_here + lookahead);
  const Vec2 d = target - own_->position;
  const Vec2 fwd = direction(own_->yaw);
  const double x = d.dot(fwd);
  const double y = fwd.x() * d.y() - fwd.y() * d.x();
  const double l2 = std::max(d.squaredNorm(), 1e-6);
  const double curvature = x > 0.0 ? 2.0 * y / l2 : std::copysign(2.0 / std::sqrt(l2), y);
  const double steer = std::atan(vehicle_.wheelbase_m * curvature);

  // Spacing: along the trail to the leader.
  gap_m_ = std::max(0.0, trail_length() - s_here) + (leader_->position - trail_.back()).norm();
  const double desired = config_.standstill_m + config_.time_gap_s * own_->speed;
  target_speed_ = lost_ ? 0.0
                        : std::clamp(leader_->speed + config_.gap_gain_per_s * (gap_m_ - desired),
                                     0.0, config_.max_speed_mps);
  const double signal = speed_pid_.update(target_speed_ - own_->speed, dt);

  vehicle::DriverInputs cmd;
  cmd.steering = std::clamp(steer / vehicle_.max_steer_rad, -1.0, 1.0);
  cmd.throttle = signal > 0.0 ? std::min(signal, 1.0) : 0.0;
  cmd.braking = signal < 0.0 ? std::min(-signal, 1.0) : 0.0;
  if (target_speed_ == 0.0 && own_->speed < 0.5) {
    cmd.throttle = 0.0;
    cmd.braking = 1.0;  // hold at rest
    speed_pid_.reset();
  }
  return cmd;
}

}  // namespace syndds::convoy

namespace syndds::convoy {

template <typename Archive>
void ConvoyFollower::state_io(Archive& a) {
  a.begin("convoy_follower", 1);
  speed_pid_.state_io(a);
  for (auto* e : {&own_, &leader_}) {
    bool has = e->has_value();
    a.io(has);
    if constexpr (std::is_same_v<Archive, core::StateReader>) {
      if (has) e->emplace(); else e->reset();
    }
    if (has) {
      a.io((*e)->position);
      a.io((*e)->yaw);
      a.io((*e)->speed);
    }
  }
  a.io(speed_reading_);
  a.io(yaw_reading_);
  a.io(leader_seen_s_);
  a.io(leader_sequence_);
  a.io(has_leader_sequence_);
  a.io(lost_);
  a.io(trail_);
  a.io(trail_s_);
  std::uint64_t index = trail_index_;
  a.io(index);
  trail_index_ = static_cast<std::size_t>(index);
  a.io(gap_m_);
  a.io(target_speed_);
  a.end();
}

void ConvoyFollower::save_state(core::StateWriter& w) const {
  const_cast<ConvoyFollower*>(this)->state_io(w);  // the writer only reads
}

void ConvoyFollower::load_state(core::StateReader& r) { state_io(r); }

}  // namespace syndds::convoy
