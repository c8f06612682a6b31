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

// No tyre brakes a vehicle harder than about 0.9 g, nor drives it harder than half that: a
// wheel speed that falls faster is a locked wheel (it reads 0 while the vehicle still slides),
// a V2V speed difference beyond these is noise or a lock.
constexpr double kMaxDecelMps2 = 9.0;
constexpr double kMaxAccelMps2 = 5.0;
// A deceleration below this is cruising: the leader is not braking to a stop.
constexpr double kBrakingMps2 = 0.1;
// Slower than this (its tachometer's noise is about 0.01 m/s) the leader stands still.
constexpr double kMovingMps = 0.2;
// Below this speed, asked for less than this, the follower holds the brake.
constexpr double kHoldMps = 0.3;
// Own yaw rate: compass differences smoothed over this time.
constexpr double kYawRateS = 0.2;
// Understeer learned from the follower's own driving: memory, the evidence the configured
// starting value weighs, the speeds and lateral accelerations that count, and its bounds.
constexpr double kUndersteerMemoryS = 10.0;
constexpr double kUndersteerPrior = 1.0;
constexpr double kUndersteerMinMps = 2.0;
constexpr double kUndersteerMinAccel = 0.3;
constexpr double kUndersteerMin = -0.02;
constexpr double kUndersteerMax = 0.1;
// Share of the GPS gain taken across the heading: dead reckoning holds the lateral position
// better than along the track (no wheel slip across), so the fixes' noise is filtered harder.
constexpr double kAcrossShare = 0.33;
// Steering: the curvature is read this long ahead (the steering's own lag and the frame of
// latency of the command), averaged over +- this window of trail (the crumbs' compass yaws
// are noisy, 0.01 rad each); the cross-track gain is softened at low speed by this speed.
constexpr double kPreviewS = 0.15;
constexpr double kCurvatureWindowM = 2.0;
constexpr double kSoftSpeedMps = 1.0;
Vec2 direction(double yaw) { return Vec2(std::cos(yaw), std::sin(yaw)); }

// Pulls an estimate towards a measurement, with one gain along `yaw` and another across it.
// The first fixes are averaged (gain 1 / n) until the gains fall to their steady values, so
// that the estimate does not start with the first fix's whole noise and take seconds to
// forget it (a wiggle the trail would keep).
void fuse(Vec2& estimate, const Vec2& measured, double yaw, double along, double across) {
  const Vec2 d = direction(yaw);
  const Vec2 n(-d.y(), d.x());
  const Vec2 innovation = measured - estimate;
  estimate += along * innovation.dot(d) * d + across * innovation.dot(n) * n;
}

// Kinematic side slip of the mid-wheelbase point: turning about a centre on the rear axle's
// line, it moves at asin(L/2 * k) to the body's heading (k = r / v, its path's curvature),
// towards the inside of the turn (0.17 rad on a 10 m radius). Dead reckoning along the body's
// heading would drift outwards in every bend.
double mid_slip(double wheelbase, double yaw_rate, double speed) {
  if (speed < 0.5) return 0.0;
  return std::asin(std::clamp(0.5 * wheelbase * yaw_rate / speed, -1.0, 1.0));
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
      speed_pid_(config_.speed_pid, 5.0),
      understeer_(config_.understeer_rad_per_mps2) {}

void ConvoyFollower::update_own(double time_s, double dt, const OwnReadings& own) {
  // Yaw rate: the compass readings' differences, smoothed over about kYawRateS.
  for (const auto& c : own.compass) {
    const double yaw = yaw_from_heading(c.heading_rad);
    const double between = c.stamp.time_s - compass_time_s_;
    if (yaw_reading_ && compass_time_s_ >= 0.0 && between > 1e-9) {
      const double rate = std::clamp(wrap_angle(yaw - *yaw_reading_) / between, -2.0, 2.0);
      own_yaw_rate_ += between / (kYawRateS + between) * (rate - own_yaw_rate_);
    }
    yaw_reading_ = yaw;
    compass_time_s_ = c.stamp.time_s;
  }
  if (!own.wheel_speeds.empty()) {
    const double tachometer = tachometer_speed(own.wheel_speeds.back().wheel_spin_rad_s,
                                               vehicle_.wheel_radius_m);
    // Locked wheels read 0 while the vehicle slides on: the speed falls no faster than a
    // vehicle can brake.
    const double floor = own_ ? own_->speed - kMaxDecelMps2 * dt : -1e9;
    speed_reading_ = std::max(tachometer, floor);
  }
  const double slip = own_ ? mid_slip(vehicle_.wheelbase_m, own_yaw_rate_, own_->speed) : 0.0;
  if (own_) {
    // Dead reckoning along the direction of motion: the heading plus the side slip.
    own_->position += own_->speed * dt * direction(own_->yaw + slip);
    if (yaw_reading_) own_->yaw = *yaw_reading_;
    own_->speed = speed_reading_;
  }
  for (const auto& fix : own.gps) {
    if (!yaw_reading_) continue;  // a fix is only useful with a heading to project it along
    const Vec3 enu = converter_.to_enu({fix.latitude_deg, fix.longitude_deg, fix.altitude_m});
    const double age = std::max(0.0, time_s - fix.stamp.time_s);
    const Vec2 now =
        Vec2(enu.x(), enu.y()) + speed_reading_ * age * direction(*yaw_reading_ + slip);
    if (!own_) {
      own_ = Estimate{now, *yaw_reading_, speed_reading_};
    } else {
      const double first = 1.0 / static_cast<double>(++own_fixes_ + 1);
      fuse(own_->position, now, own_->yaw, std::max(config_.fix_gain, first),
           std::max(kAcrossShare * config_.fix_gain, first));
    }
  }
}

bool ConvoyFollower::track(Tracked& t, const std::string& id, double wheelbase_m, double time_s,
                           double dt, const std::vector<proto::V2VMessageMsg>& msgs) const {
  if (t.estimate) {
    auto& e = *t.estimate;
    const double slip = mid_slip(wheelbase_m, t.yaw_rate, e.speed);
    const double heading = e.yaw + 0.5 * t.yaw_rate * dt + slip;
    e.position += e.speed * dt * direction(heading);
    e.yaw = wrap_angle(e.yaw + t.yaw_rate * dt);
  }
  bool fused = false;
  for (const auto& m : msgs) {
    if (m.vehicle_id != id) continue;
    // A message older than one already used (reordered, replayed) tells nothing new.
    if (t.has_sequence && m.sequence <= t.sequence) continue;
    t.sequence = m.sequence;
    t.has_sequence = true;
    t.seen_s = std::max(t.seen_s, m.sensor_time_s);
    const Vec3 enu = converter_.to_enu({m.latitude_deg, m.longitude_deg, m.altitude_m});
    const double yaw = yaw_from_heading(m.heading_rad);
    const double age = std::max(0.0, time_s - m.sensor_time_s);
    if (!t.estimate) {
      const Vec2 now = Vec2(enu.x(), enu.y()) + m.speed_mps * age * direction(yaw);
      t.estimate = Estimate{now, yaw, m.speed_mps};
    } else {
      // Acceleration and yaw rate: the changes of the tachometer speed and of the compass
      // heading since the previous message, over the time between their arrivals (a fixed
      // number of frames after each was built); the yaw rate smoothed over about two messages.
      const double between = time_s - t.speed_time_s;
      if (t.speed_time_s >= 0.0 && between > 1e-9) {
        t.accel = std::clamp((m.speed_mps - t.speed) / between, -kMaxDecelMps2, kMaxAccelMps2);
        const double rate = std::clamp(wrap_angle(yaw - t.heading_yaw) / between, -2.0, 2.0);
        t.yaw_rate += 0.5 * (rate - t.yaw_rate);
      }
      const double slip = mid_slip(wheelbase_m, t.yaw_rate, m.speed_mps);
      const Vec2 now = Vec2(enu.x(), enu.y()) + m.speed_mps * age * direction(yaw + slip);
      const double first = 1.0 / static_cast<double>(++t.fixes + 1);
      fuse(t.estimate->position, now, yaw, std::max(config_.leader_fix_gain, first),
           std::max(kAcrossShare * config_.leader_fix_gain, first));
      t.estimate->yaw = yaw;
      t.estimate->speed = m.speed_mps;
    }
    t.speed = m.speed_mps;
    t.heading_yaw = yaw;
    t.speed_time_s = time_s;
    fused = true;
  }
  return fused;
}

void ConvoyFollower::extend_trail() {
  const Estimate& source = *trail_source().estimate;
  if (trail_.empty()) {
    // The trail starts where the follower stands: the stretch to the source's first reported
    // position is the one part it has not seen the source drive (its direction is its yaw).
    trail_.push_back(own_->position);
    trail_yaw_.push_back(source.yaw);
    trail_s_.push_back(0.0);
  }
  // Only a moving source lays crumbs: standing, its estimate wanders with the GPS noise, and
  // crumbs laid back and forth would lengthen the trail (the gap) that is not there.
  const double d = (source.position - trail_.back()).norm();
  if (d < config_.crumb_spacing_m || source.speed < kMovingMps) return;
  if (trail_.size() == 1 && d > 1.0) {
    const Vec2 to = source.position - trail_.back();
    trail_yaw_[0] = std::atan2(to.y(), to.x());
  }
  trail_.push_back(source.position);
  trail_yaw_.push_back(source.yaw);
  trail_s_.push_back(trail_s_.back() + d);
}

ConvoyFollower::Projection ConvoyFollower::projection(const Vec2& p, std::size_t from) const {
  // Search forward from the last segment: progress is monotone, so a trail that loops back
  // near itself is never taken by its later part too early.
  double best_d2 = std::numeric_limits<double>::infinity();
  Projection best;
  best.s = trail_s_.empty() ? 0.0 : trail_s_[from];
  best.index = from;
  for (std::size_t i = from; i + 1 < trail_.size(); ++i) {
    const Vec2 a = trail_[i];
    const Vec2 ab = trail_[i + 1] - a;
    const double len2 = ab.squaredNorm();
    const double u = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    const double d2 = (a + u * ab - p).squaredNorm();
    if (d2 < best_d2) {
      best_d2 = d2;
      best.index = i;
      best.s = trail_s_[i] + u * std::sqrt(len2);
      // Signed: > 0 when the follower is left of the trail.
      const Vec2 ap = p - a;
      best.cross_track_m = len2 > 0.0 ? (ab.x() * ap.y() - ab.y() * ap.x()) / std::sqrt(len2) : 0.0;
    }
    if (trail_s_[i] > best.s + 30.0) break;  // far enough past the best: stop looking
  }
  if (!std::isfinite(best_d2)) best.cross_track_m = 0.0;
  return best;
}

ConvoyFollower::Projection ConvoyFollower::leader_on_trail() const {
  return projection(lead_.estimate->position, std::max(leader_index_, trail_index_));
}

double ConvoyFollower::project_on_trail(const Vec2& p) {
  const Projection pr = projection(p);
  trail_index_ = pr.index;
  cross_track_m_ = pr.cross_track_m;
  return pr.s;
}

double ConvoyFollower::centres_to_leader(double s_here) const {
  const Estimate& leader = *lead_.estimate;
  if (trail_apart()) {
    // The leader drives on the trail (the source's): its projection on it, or beyond the
    // trail's end along its heading, as when the trail is its own.
    const Projection pr = leader_on_trail();
    const double beyond =
        pr.s < trail_length() ? 0.0 : (leader.position - trail_.back()).dot(direction(leader.yaw));
    return pr.s - s_here + std::max(0.0, beyond);
  }
  // The leader's estimate beyond the newest crumb, signed along the leader's heading (it may
  // lie behind it: the GPS pulled the estimate back after the crumb was laid).
  const double beyond = (leader.position - trail_.back()).dot(direction(leader.yaw));
  return std::max(0.0, trail_length() - s_here) + beyond;
}

TrailFeatures ConvoyFollower::trail_features() const {
  TrailFeatures f;
  if (!own_ || !lead_.estimate || !trail_source().estimate || trail_.empty()) return f;
  const Estimate& leader = *lead_.estimate;
  f.valid = true;
  const Projection pr = projection(own_->position);
  f.cross_track_m = pr.cross_track_m;
  f.heading_error_rad = wrap_angle(trail_yaw(pr.s) - own_->yaw);
  for (std::size_t i = 0; i < f.curvature_per_m.size(); ++i) {
    f.curvature_per_m[i] =
        trail_curvature(pr.s + TrailFeatures::kCurvatureAheadM[i], kCurvatureWindowM);
  }
  f.own_speed_mps = own_->speed;
  f.leader_speed_mps = leader.speed;
  f.leader_accel_mps2 = lead_.accel;
  f.gap_m = centres_to_leader(pr.s) - vehicle_.front_m - vehicle_.leader_rear_m;
  const Vec2 rel = leader.position - own_->position;
  const Vec2 d = direction(own_->yaw);
  f.leader_forward_m = rel.dot(d);
  f.leader_left_m = d.x() * rel.y() - d.y() * rel.x();
  f.leader_lost = lost_;
  const double v = std::max(own_->speed, 0.0);
  const double k_ahead = trail_curvature(pr.s + v * kPreviewS, kCurvatureWindowM);
  f.feedforward_steering =
      steering_input(std::clamp(kinematic_angle(k_ahead) + understeer_ * v * v * k_ahead,
                                -max_bicycle_angle(), max_bicycle_angle()));
  return f;
}

Vec2 ConvoyFollower::trail_point(double s) const {
  if (s >= trail_length()) {
    // Past the newest crumb: towards the source's estimated position.
    const Vec2 last = trail_.back();
    const Vec2 to_leader = trail_source().estimate->position - last;
    const double rest = to_leader.norm();
    if (rest < 1e-9) return last;
    return last + std::min(1.0, (s - trail_length()) / rest) * to_leader;
  }
  const auto it = std::upper_bound(trail_s_.begin(), trail_s_.end(), s);
  const std::size_t i =
      static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - trail_s_.begin() - 1, 0));
  const double len = trail_s_[i + 1] - trail_s_[i];
  const double u = len > 0.0 ? (s - trail_s_[i]) / len : 0.0;
  return trail_[i] + u * (trail_[i + 1] - trail_[i]);
}

double ConvoyFollower::trail_yaw(double s) const {
  if (s <= 0.0 || trail_.size() < 2) return trail_yaw_.front();
  if (s >= trail_length()) return trail_yaw_.back();
  const auto it = std::upper_bound(trail_s_.begin(), trail_s_.end(), s);
  const std::size_t i =
      static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - trail_s_.begin() - 1, 0));
  const double len = trail_s_[i + 1] - trail_s_[i];
  const double u = len > 0.0 ? (s - trail_s_[i]) / len : 0.0;
  return trail_yaw_[i] + u * wrap_angle(trail_yaw_[i + 1] - trail_yaw_[i]);
}

double ConvoyFollower::trail_curvature(double s, double w) const {
  const double a = std::clamp(s - w, 0.0, trail_length());
  const double b = std::clamp(s + w, 0.0, trail_length());
  if (b - a < 0.5) return 0.0;
  return wrap_angle(trail_yaw(b) - trail_yaw(a)) / (b - a);
}

double ConvoyFollower::kinematic_angle(double k) const {
  // The reference point (mid-wheelbase) on radius R turns about a centre on the rear axle's
  // line at R_rear = sqrt(R^2 - (L/2)^2) from the rear axle's centre: tan(delta) = L / R_rear.
  if (std::abs(k) < 1e-9) return 0.0;
  const double l = vehicle_.wheelbase_m;
  const double r = 1.0 / std::abs(k);
  const double r_rear = std::sqrt(std::max(r * r - 0.25 * l * l, 1e-6));
  return std::copysign(std::atan(l / r_rear), k);
}

double ConvoyFollower::max_bicycle_angle() const {
  if (!vehicle_.inner_wheel_input) return vehicle_.max_steer_rad;
  const double l = vehicle_.wheelbase_m;
  return std::atan(l / (l / std::tan(vehicle_.max_steer_rad) + vehicle_.half_track_m));
}

double ConvoyFollower::steering_input(double bicycle_angle, double limit) const {
  if (!vehicle_.inner_wheel_input) {
    return std::clamp(bicycle_angle / vehicle_.max_steer_rad, -limit, limit);
  }
  // The input sets the inner road wheel (docs/vehicle-dynamics.md): for the bicycle's turn
  // radius R_rear = L / tan(delta) at the rear axle, tan(inner) = L / (R_rear - t/2).
  const double t = std::tan(std::min(std::abs(bicycle_angle), 1.5));
  if (t < 1e-12) return 0.0;
  const double l = vehicle_.wheelbase_m;
  const double denominator = l / t - vehicle_.half_track_m;
  const double inner = denominator > 1e-6 ? std::atan(l / denominator) : std::numbers::pi / 2.0;
  return std::copysign(std::min(inner / vehicle_.max_steer_rad, limit), bicycle_angle);
}

void ConvoyFollower::learn_understeer(double dt, double v) {
  // Road-wheel angle = kinematic angle of the curvature driven + K * lateral acceleration: K
  // by least squares over the last kUndersteerMemoryS of the follower's own steering and
  // compass (about 0.001 rad per m/s2 on rigid ground, 0.017 on hard soil, 0.06 on soft), so
  // that the feed-forward turns as much as this ground needs. Starts from the configured value,
  // weighted as kUndersteerPrior (m/s2)^2 s of evidence; the memory counts time in bends.
  const double ay = v * own_yaw_rate_;
  if (v > kUndersteerMinMps && std::abs(ay) > kUndersteerMinAccel) {
    // Old evidence fades only while new comes in: on a straight the estimate keeps its value.
    const double forget = std::exp(-dt / kUndersteerMemoryS);
    const double residual = steer_smoothed_ - kinematic_angle(own_yaw_rate_ / v);
    understeer_num_ = forget * understeer_num_ + residual * ay * dt;
    understeer_den_ = forget * understeer_den_ + ay * ay * dt;
  }
  const double prior = config_.understeer_rad_per_mps2 * kUndersteerPrior;
  understeer_ = std::clamp((understeer_num_ + prior) / (understeer_den_ + kUndersteerPrior),
                           kUndersteerMin, kUndersteerMax);
}

bool KeepOut::in_view(const Circle& ob, const Vec2& position, double yaw) const {
  if (view_half_angle_rad <= 0.0) return true;
  const Vec2 heading(std::cos(yaw), std::sin(yaw));
  const Vec2 rel = ob.centre - (position + view_ahead_m * heading);
  const double ahead = rel.dot(heading);
  const double side = std::abs(heading.x() * rel.y() - heading.y() * rel.x());
  if (ahead <= -ob.radius_m) return false;
  // The circle meets the wedge when its centre is inside it or within its radius of the
  // wedge's edge (the ray from the camera at the half angle).
  const double c = std::cos(view_half_angle_rad), s = std::sin(view_half_angle_rad);
  if (side * c <= ahead * s) return true;  // centre inside
  const double along = ahead * c + side * s;  // projection on the edge ray
  const double off = along > 0.0 ? std::abs(side * c - ahead * s) : rel.norm();
  return off < ob.radius_m;
}

double ConvoyFollower::keep_out_shift(double s_here) const {
  if (keep_out_.obstacles.empty() || trail_.size() < 2) return 0.0;
  double push_left = 0.0, push_right = 0.0;
  for (const auto& ob : keep_out_.obstacles) {
    if (!keep_out_.in_view(ob, own_->position, own_->yaw)) continue;
    // The obstacle's projection on the trail from just behind the follower (an obstacle
    // beside its body) to past the lead-in (the trail is known only where the leader has
    // driven: an obstacle beyond it waits its turn). One found at either end of that window
    // is outside the shift's reach.
    std::size_t first = trail_index_;
    while (first > 0 && trail_s_[first] > s_here - 2.0 * ob.radius_m - 4.0) --first;
    double best_d2 = std::numeric_limits<double>::infinity(), s_ob = 0.0, left = 0.0;
    for (std::size_t i = first; i + 1 < trail_.size(); ++i) {
      if (trail_s_[i] > s_here + keep_out_.lead_in_m + 2.0 * ob.radius_m) break;
      const Vec2 a = trail_[i];
      const Vec2 ab = trail_[i + 1] - a;
      const double len2 = ab.squaredNorm();
      if (len2 <= 0.0) continue;
      const double u = std::clamp((ob.centre - a).dot(ab) / len2, 0.0, 1.0);
      const double d2 = (a + u * ab - ob.centre).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        s_ob = trail_s_[i] + u * std::sqrt(len2);
        const Vec2 ac = ob.centre - a;
        left = ab.x() * ac.y() - ab.y() * ac.x();  // its sign: the side
      }
    }
    if (!std::isfinite(best_d2)) continue;
    // The distance to the trail (not to a segment's line: an obstacle beyond the trail's
    // first crumb is as far as it is from that crumb).
    const double need = std::min(keep_out_.max_shift_m,
                                 keep_out_.clearance_m - (std::sqrt(best_d2) - ob.radius_m));
    if (need <= 0.0 || s_here > s_ob + ob.radius_m + 2.0) continue;
    const double start = s_ob - ob.radius_m - keep_out_.lead_in_m;
    const double push = need * std::clamp((s_here - start) / keep_out_.ramp_m, 0.0, 1.0);
    if (left > 0.0) {
      push_right = std::max(push_right, push);
    } else {
      push_left = std::max(push_left, push);
    }
  }
  return push_left - push_right;
}

void ConvoyFollower::observe_radar(const std::vector<proto::RadarScanMsg>& scans) {
  if (config_.radar_sensor.empty()) return;
  for (const auto& scan : scans) {
    if (scan.stamp.sensor_id != config_.radar_sensor || scan.stamp.time_s < radar_time_s_) continue;
    // Detections come by range: the first in the lane is the nearest.
    for (const auto& d : scan.detections) {
      if (d.x <= 0.0f || std::abs(d.y) > config_.radar_lane_half_width_m) continue;
      radar_time_s_ = scan.stamp.time_s;
      radar_gap_m_ = d.x + vehicle_.radar_ahead_of_front_m;
      radar_range_rate_ = d.radial_speed_mps;
      break;
    }
  }
}

vehicle::DriverInputs ConvoyFollower::update(double time_s, double dt, const OwnReadings& own,
                                             const std::vector<proto::V2VMessageMsg>& leader,
                                             std::vector<FollowerEvent>& events) {
  steering_beyond_lock_ = 0.0;
  update_own(time_s, dt, own);
  bool fused = track(lead_, config_.leader, vehicle_.leader_wheelbase_m, time_s, dt, leader);
  if (trail_apart()) {
    fused = track(head_, config_.trail_of, vehicle_.trail_wheelbase_m, time_s, dt, leader);
  }
  vehicle::DriverInputs hold;
  hold.braking = 1.0;
  if (!own_) return hold;  // no fix or heading yet: stay put

  // Leader lost / found, by the measurement time of its newest message (and of the trail's
  // source's: without it the trail ends).
  const auto silence_of = [&](const Tracked& t) {
    return t.seen_s < 0.0 ? time_s : time_s - t.seen_s;
  };
  std::string silent = config_.leader;
  double silence = silence_of(lead_);
  if (trail_apart() && silence_of(head_) > silence) {
    silent = config_.trail_of;
    silence = silence_of(head_);
  }
  if (!lost_ && silence > config_.leader_lost_after_s) {
    lost_ = true;
    std::ostringstream detail;
    detail << "no v2v message from " << silent << " for " << std::fixed
           << std::setprecision(2) << silence << " s";
    events.push_back({"leader_lost", detail.str()});
  } else if (lost_ && silence <= config_.leader_lost_after_s) {
    lost_ = false;
    events.push_back({"leader_found", "v2v messages from " + config_.leader +
                                          (trail_apart() ? " and " + config_.trail_of : "") +
                                          " again"});
  }
  if (!lead_.estimate || !trail_source().estimate) return hold;
  if (fused || trail_.empty()) extend_trail();

  // Steering: the trail's curvature ahead as a feed-forward, the leader's heading there and
  // the distance to the trail as feedback.
  const double s_here = project_on_trail(own_->position);
  const double v = std::max(own_->speed, 0.0);
  const double k_ahead = trail_curvature(s_here + v * kPreviewS, kCurvatureWindowM);
  learn_understeer(dt, v);
  double angle = kinematic_angle(k_ahead) + understeer_ * v * v * k_ahead;
  angle += config_.heading_gain * wrap_angle(trail_yaw(s_here) - own_->yaw);
  const double before_cross_track = angle;
  angle -= std::atan(config_.cross_track_gain_per_s * cross_track_m_ / (v + kSoftSpeedMps));
  angle = std::clamp(angle, -max_bicycle_angle(), max_bicycle_angle());
  // The angle as the yaw rate will show it: through the same smoothing.
  steer_smoothed_ += dt / (kYawRateS + dt) * (angle - steer_smoothed_);
  // A map's shift changes the command only (KeepOut): every estimate, the understeer learned
  // from the commanded angle included, stays the one without the map.
  keep_shift_ = keep_out_shift(s_here);
  const double commanded =
      keep_shift_ == 0.0
          ? angle
          : std::clamp(before_cross_track -
                           std::atan(config_.cross_track_gain_per_s *
                                     (cross_track_m_ - keep_shift_) / (v + kSoftSpeedMps)),
                       -max_bicycle_angle(), max_bicycle_angle());

  // Spacing: bumper to bumper along the trail.
  if (trail_apart()) leader_index_ = leader_on_trail().index;
  gap_m_ = centres_to_leader(s_here) - vehicle_.front_m - vehicle_.leader_rear_m;
  double v_leader = std::max(lead_.estimate->speed, 0.0);
  radar_used_ = false;
  if (radar_time_s_ >= 0.0 && time_s - radar_time_s_ <= config_.radar_max_age_s) {
    const double radar_gap = radar_gap_m_ + radar_range_rate_ * (time_s - radar_time_s_);
    if (std::abs(radar_gap - gap_m_) <= config_.radar_gate_m) {
      gap_m_ = radar_gap;
      v_leader = std::max(0.0, v + radar_range_rate_);
      radar_used_ = true;
    }
  }
  const double decel = -lead_.accel;
  // Where the leader would stop at its present deceleration, against where the follower would
  // at its own: the difference is room the time gap does not give.
  const double leader_stop = v_leader <= 0.0 ? 0.0
                             : decel > kBrakingMps2
                                 ? v_leader * v_leader / (2.0 * decel)
                                 : std::numeric_limits<double>::infinity();
  const double own_stop = v * v / (2.0 * config_.own_decel_mps2);
  desired_gap_m_ = config_.standstill_bumper_m + config_.time_gap_s * v +
                   std::max(0.0, own_stop - leader_stop);
  const double predicted = std::max(0.0, v_leader + lead_.accel * config_.anticipation_s);
  const double target = predicted + config_.gap_gain_per_s * (gap_m_ - desired_gap_m_);
  target_speed_ = lost_ ? 0.0 : std::clamp(target, 0.0, config_.max_speed_mps);
  const double signal = speed_pid_.update(target_speed_ - own_->speed, dt);

  vehicle::DriverInputs cmd;
  cmd.steering = steering_input(commanded);
  // The same command without the lock (the bicycle angle's and the input's): the angle has
  // no bound but the input's mapping saturates where the inner wheel would reach 90 degrees.
  const double unlocked = before_cross_track - std::atan(config_.cross_track_gain_per_s *
                                                         (cross_track_m_ - keep_shift_) /
                                                         (v + kSoftSpeedMps));
  steering_beyond_lock_ = steering_input(unlocked, std::numeric_limits<double>::infinity());
  cmd.throttle = signal > 0.0 ? std::min(signal, 1.0) : 0.0;
  cmd.braking = signal < 0.0 ? std::min(-signal, 1.0) : 0.0;
  if (target_speed_ < kHoldMps && own_->speed < kHoldMps) {
    // Stopped, or about to, with no more than a crawl asked for: hold on the brake. A crawl
    // would only close the last metre on the idling engine's torque, with the GPS's error.
    cmd.throttle = 0.0;
    cmd.braking = 1.0;
    speed_pid_.reset();
  }
  return cmd;
}

}  // namespace syndds::convoy

namespace syndds::convoy {

template <typename Archive>
void ConvoyFollower::tracked_io(Archive& a, Tracked& t) {
  bool has = t.estimate.has_value();
  a.io(has);
  if constexpr (std::is_same_v<Archive, core::StateReader>) {
    if (has) t.estimate.emplace(); else t.estimate.reset();
  }
  if (has) {
    a.io(t.estimate->position);
    a.io(t.estimate->yaw);
    a.io(t.estimate->speed);
  }
  a.io(t.seen_s);
  a.io(t.sequence);
  a.io(t.has_sequence);
  a.io(t.speed_time_s);
  a.io(t.accel);
  a.io(t.speed);
  a.io(t.heading_yaw);
  a.io(t.yaw_rate);
  a.io(t.fixes);
}

template <typename Archive>
void ConvoyFollower::state_io(Archive& a) {
  // Version 2 (before the radar gap) holds no radar detection; version 3 no trail source
  // apart from the leader.
  const std::uint32_t version = [&] {
    if constexpr (std::is_same_v<Archive, core::StateReader>) {
      return a.begin("convoy_follower", 4, 2);
    } else {
      a.begin("convoy_follower", 4);
      return std::uint32_t{4};
    }
  }();
  speed_pid_.state_io(a);
  // The order of versions 2 and 3: both estimates, then the leader's filter.
  for (auto* e : {&own_, &lead_.estimate}) {
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
  a.io(lead_.seen_s);
  a.io(lead_.sequence);
  a.io(lead_.has_sequence);
  a.io(lead_.speed_time_s);
  a.io(lead_.accel);
  a.io(lead_.speed);
  a.io(lead_.heading_yaw);
  a.io(lead_.yaw_rate);
  a.io(own_fixes_);
  a.io(lead_.fixes);
  a.io(compass_time_s_);
  a.io(own_yaw_rate_);
  a.io(steer_smoothed_);
  a.io(understeer_num_);
  a.io(understeer_den_);
  a.io(understeer_);
  a.io(lost_);
  a.io(trail_);
  a.io(trail_yaw_);
  a.io(trail_s_);
  std::uint64_t index = trail_index_;
  a.io(index);
  trail_index_ = static_cast<std::size_t>(index);
  a.io(gap_m_);
  a.io(desired_gap_m_);
  a.io(target_speed_);
  a.io(cross_track_m_);
  if (version >= 3) {
    a.io(radar_time_s_);
    a.io(radar_gap_m_);
    a.io(radar_range_rate_);
    a.io(radar_used_);
  }
  if (version >= 4) {
    tracked_io(a, head_);
    std::uint64_t leader_index = leader_index_;
    a.io(leader_index);
    leader_index_ = static_cast<std::size_t>(leader_index);
  }
  a.end();
}

void ConvoyFollower::save_state(core::StateWriter& w) const {
  const_cast<ConvoyFollower*>(this)->state_io(w);  // the writer only reads
}

void ConvoyFollower::load_state(core::StateReader& r) { state_io(r); }

}  // namespace syndds::convoy
