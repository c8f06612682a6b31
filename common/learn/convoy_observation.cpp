#include "learn/convoy_observation.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <type_traits>

#include "agents/follower_agent.hpp"
#include "protocol/sample_state.hpp"

namespace syndds::learn {
namespace {

// The newest of `list`'s samples of `vehicle` by measurement time, if newer than `held`.
template <typename Msg>
void take_newest(const std::vector<Msg>& list, const std::string& vehicle,
                 std::optional<Msg>& held) {
  for (const Msg& m : list) {
    if (m.vehicle_id != vehicle) continue;
    if (!held || m.stamp.time_s >= held->stamp.time_s) held = m;
  }
}

// A reading held or not, and then every field of it.
template <typename Archive, typename Msg>
void held_io(Archive& a, std::optional<Msg>& held) {
  bool has = held.has_value();
  a.io(has);
  if constexpr (std::is_same_v<Archive, core::StateReader>) {
    if (has) {
      held.emplace();
    } else {
      held.reset();
    }
  }
  if (has) proto::message_io(a, *held);
}

}  // namespace

bool observes_trail(ConvoyObservationKind kind) {
  return kind == ConvoyObservationKind::trail || kind == ConvoyObservationKind::trail_action ||
         kind == ConvoyObservationKind::trail_ff || kind == ConvoyObservationKind::trail_ff_memory;
}

bool has_memory(ConvoyObservationKind kind) {
  return kind == ConvoyObservationKind::trail_ff_memory;
}

Box convoy_action_space(ConvoyObservationKind kind) {
  Box b{{-1.0f, -1.0f}, {1.0f, 1.0f}, {"steering", "throttle_brake"}};
  if (has_memory(kind)) {
    b.low.push_back(-1.0f);
    b.high.push_back(1.0f);
    b.names.push_back("memory");
    b.explore = {true, true, false};
  }
  return b;
}

ConvoyObservationKind parse_observation_kind(const std::string& name) {
  if (name == "paper") return ConvoyObservationKind::paper;
  if (name == "trail") return ConvoyObservationKind::trail;
  if (name == "trail_action") return ConvoyObservationKind::trail_action;
  if (name == "trail_ff") return ConvoyObservationKind::trail_ff;
  if (name == "trail_ff_memory") return ConvoyObservationKind::trail_ff_memory;
  throw std::invalid_argument("observation '" + name +
                              "' is not one of paper, trail, trail_action, trail_ff, "
                              "trail_ff_memory");
}

ConvoyObservationConfig convoy_observation_config(const scenario::Scenario& scenario,
                                                  const scenario::VehicleConfig& follower,
                                                  const std::string& leader_id,
                                                  ConvoyObservationKind kind) {
  if (!follower.sensors || follower.sensors->rig.gps.empty()) {
    throw std::invalid_argument("convoy follower '" + follower.id + "' has no GPS");
  }
  const auto& rig = follower.sensors->rig;
  ConvoyObservationConfig c;
  c.kind = kind;
  c.follower_id = follower.id;
  c.leader_id = leader_id;
  c.geodetic_origin = rig.geodetic_origin;
  c.geodetic_model = rig.gps.front().model;
  c.wheel_radius_m = follower.params.wheels.radius_m;
  if (!rig.cameras.empty()) {
    c.image = ImageSpec{rig.cameras.front().intrinsics.width,
                        rig.cameras.front().intrinsics.height, 3};
    c.camera_id = rig.cameras.front().id;
  }
  c.estimator.leader = leader_id;
  // A scenario's follower may steer along its convoy head's trail (controller trail: head).
  if (follower.controller.follows() && follower.controller.convoy.leader == leader_id) {
    c.estimator.trail_of = follower.controller.convoy.trail_of;
  }
  c.vehicle = agents::follower_vehicle(follower, scenario.find_vehicle(leader_id),
                                       scenario.find_vehicle(c.estimator.trail_of));
  return c;
}

ConvoyObservationBuilder::ConvoyObservationBuilder(ConvoyObservationConfig config)
    : config_(std::move(config)), converter_(config_.geodetic_origin, config_.geodetic_model) {
  if (observes_trail(config_.kind)) {
    estimator_.emplace(config_.estimator, config_.vehicle, converter_);
    estimator_->set_keep_out(config_.teacher_keep_out);
  }
}

bool has_feedforward(ConvoyObservationKind kind) {
  return kind == ConvoyObservationKind::trail_ff || has_memory(kind);
}

Box ConvoyObservationBuilder::vector_space(ConvoyObservationKind kind) {
  if (observes_trail(kind)) {
    Box b{{-50.0f, -1.0f, -1.0f, -1.0f, -1.0f, -1.0f, -5.0f, -5.0f, -20.0f, -200.0f, -200.0f,
           -200.0f},
          {50.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 30.0f, 30.0f, 20.0f, 200.0f, 200.0f, 200.0f},
          {"cross_track_m", "heading_error_sin", "heading_error_cos", "curvature_0m_per_m",
           "curvature_5m_per_m", "curvature_10m_per_m", "speed_mps", "leader_speed_mps",
           "leader_accel_mps2", "gap_m", "leader_forward_m", "leader_left_m"}};
    if (has_feedforward(kind)) {
      b.low.push_back(-1.0f);
      b.high.push_back(1.0f);
      b.names.push_back("feedforward_steering");
    }
    if (has_memory(kind)) {
      b.low.push_back(-1.0f);
      b.high.push_back(1.0f);
      b.names.push_back("memory");
    }
    if (kind == ConvoyObservationKind::trail_action) {
      for (const char* name : {"previous_steering", "previous_throttle_brake"}) {
        b.low.push_back(-1.0f);
        b.high.push_back(1.0f);
        b.names.push_back(name);
      }
    }
    return b;
  }
  return Box{{-200.0f, -200.0f, 0.0f, -30.0f},
             {200.0f, 200.0f, 6.2832f, 30.0f},
             {"leader_north_m", "leader_east_m", "heading_rad", "closing_speed_mps"}};
}

void ConvoyObservationBuilder::consume(const proto::FrameContext& ctx,
                                       const proto::FrameSamples& s) {
  if (estimator_ && ctx.frame > 0) {
    // As the classical follower's member does: the inputs describe the end of frame k-1.
    const convoy::OwnReadings own{s.gps_fixes, s.magnetometers, s.wheel_speeds};
    std::vector<convoy::FollowerEvent> events;  // leader lost shows in the features
    const vehicle::DriverInputs command = estimator_->update(
        ctx.sim_time_s - ctx.heartbeat_s, ctx.heartbeat_s, own, s.v2v_messages, events);
    classical_action_ = {static_cast<float>(command.steering),
                         static_cast<float>(command.throttle - command.braking)};
    classical_beyond_lock_ = estimator_->steering_beyond_lock();
    teacher_shift_m_ = estimator_->keep_out_shift_m();
    if (has_memory(config_.kind)) {
      const double largest = config_.teacher_keep_out.max_shift_m;
      classical_action_.push_back(
          largest > 0.0 ? static_cast<float>(estimator_->keep_out_shift_m() / largest) : 0.0f);
    }
  }
  take_newest(s.gps_fixes, config_.follower_id, fix_);
  take_newest(s.magnetometers, config_.follower_id, compass_);
  take_newest(s.wheel_speeds, config_.follower_id, wheels_);
  if (config_.image) {
    for (const auto& m : s.images) {  // the observed camera's only
      if (m.vehicle_id != config_.follower_id || m.stamp.sensor_id != config_.camera_id) continue;
      if (!image_ || m.stamp.time_s >= image_->stamp.time_s) image_ = m;
    }
  }
  for (const auto& m : s.v2v_messages) {
    if (m.vehicle_id != config_.leader_id) continue;
    if (!v2v_ || m.sequence > v2v_->sequence) v2v_ = m;
  }
}

bool ConvoyObservationBuilder::ready() const {
  return fix_ && compass_ && wheels_ && v2v_ && (!config_.image || image_) &&
         (!estimator_ || estimator_->trail_features().valid);
}

Observation ConvoyObservationBuilder::observation() const {
  if (!ready()) throw std::logic_error("ConvoyObservationBuilder: an input has not arrived yet");
  // Positions: both latitude / longitude pairs into the local east-north frame of the GPS's
  // own origin and model, then the difference (metres: the same information as the latitude
  // and longitude difference, scaled).
  const Vec3 own = converter_.to_enu({fix_->latitude_deg, fix_->longitude_deg, fix_->altitude_m});
  const Vec3 lead = converter_.to_enu({v2v_->latitude_deg, v2v_->longitude_deg, v2v_->altitude_m});
  const double east = lead.x() - own.x(), north = lead.y() - own.y();
  // Own speed as the V2V sender computes its own: mean wheel spin times the wheel radius.
  const auto& spins = wheels_->wheel_spin_rad_s;
  const double own_speed =
      spins.empty() ? 0.0
                    : std::accumulate(spins.begin(), spins.end(), 0.0) /
                          static_cast<double>(spins.size()) * config_.wheel_radius_m;
  // Closing speed: how fast the distance to the leader shrinks, -d|r|/dt, with both vehicles
  // moving along their compass headings (clockwise from north) at their tachometer speeds.
  const double range = std::hypot(north, east);
  double closing = own_speed - v2v_->speed_mps;  // the leader straight ahead
  if (range > 1e-6) {
    const double un = north / range, ue = east / range;
    const double h_own = compass_->heading_rad, h_lead = v2v_->heading_rad;
    closing = own_speed * (std::cos(h_own) * un + std::sin(h_own) * ue) -
              v2v_->speed_mps * (std::cos(h_lead) * un + std::sin(h_lead) * ue);
  }
  Observation o;
  if (estimator_) {
    const convoy::TrailFeatures f = estimator_->trail_features();
    const double shift = config_.observe_keep_out ? teacher_shift_m_ : 0.0;
    o.vector = {static_cast<float>(f.cross_track_m - shift),
                static_cast<float>(std::sin(f.heading_error_rad)),
                static_cast<float>(std::cos(f.heading_error_rad)),
                static_cast<float>(f.curvature_per_m[0]),
                static_cast<float>(f.curvature_per_m[1]),
                static_cast<float>(f.curvature_per_m[2]),
                static_cast<float>(f.own_speed_mps),
                static_cast<float>(f.leader_speed_mps),
                static_cast<float>(f.leader_accel_mps2),
                static_cast<float>(f.gap_m),
                static_cast<float>(f.leader_forward_m),
                static_cast<float>(f.leader_left_m)};
    if (config_.kind == ConvoyObservationKind::trail_ff || has_memory(config_.kind)) {
      o.vector.push_back(static_cast<float>(f.feedforward_steering));
    }
    if (has_memory(config_.kind)) o.vector.push_back(static_cast<float>(memory_));
    if (config_.kind == ConvoyObservationKind::trail_action) {
      o.vector.push_back(static_cast<float>(previous_steering_));
      o.vector.push_back(static_cast<float>(previous_throttle_brake_));
    }
  } else {
    o.vector = {static_cast<float>(north), static_cast<float>(east),
                static_cast<float>(compass_->heading_rad), static_cast<float>(closing)};
  }
  if (config_.image) {
    if (image_->width != config_.image->width || image_->height != config_.image->height ||
        image_->data.size() != config_.image->bytes()) {
      throw std::runtime_error("ConvoyObservationBuilder: image of " +
                               std::to_string(image_->width) + " x " +
                               std::to_string(image_->height) + " px, expected " +
                               std::to_string(config_.image->width) + " x " +
                               std::to_string(config_.image->height));
    }
    o.image = image_->data;
  }
  return o;
}

void ConvoyObservationBuilder::note_action(double steering, double throttle_brake,
                                           double memory) {
  const auto applied = [](double v) { return std::isnan(v) ? 0.0 : std::clamp(v, -1.0, 1.0); };
  previous_steering_ = applied(steering);
  previous_throttle_brake_ = applied(throttle_brake);
  memory_ = has_memory(config_.kind) ? applied(memory) : 0.0;
}

void ConvoyObservationBuilder::observe_ranges(const convoy::RangeReading& reading) {
  if (!config_.teacher_keep_out_perceived || !estimator_ || !estimator_->ready()) return;
  teacher_memory_.observe(estimator_->position_estimate(), estimator_->yaw_estimate(), reading);
  convoy::KeepOut keep_out = config_.teacher_keep_out;
  keep_out.obstacles = teacher_memory_.circles();
  estimator_->set_keep_out(std::move(keep_out));
}

template <typename Archive>
void ConvoyObservationBuilder::state_io(Archive& a) {
  a.begin("convoy_observation", 1);
  held_io(a, fix_);
  held_io(a, compass_);
  held_io(a, wheels_);
  held_io(a, v2v_);
  held_io(a, image_);
  if (estimator_) {  // the trail kind's estimator (both sides have the same configuration)
    if constexpr (std::is_same_v<Archive, core::StateWriter>) {
      estimator_->save_state(a);
    } else {
      estimator_->load_state(a);
    }
  }
  if (config_.kind == ConvoyObservationKind::trail_action) {
    a.io(previous_steering_);
    a.io(previous_throttle_brake_);
  }
  if (has_memory(config_.kind)) a.io(memory_);
  if (config_.teacher_keep_out_perceived) {  // what the obstacle map has seen (a controller's)
    a.io(teacher_shift_m_);
    teacher_memory_.state_io(a);
    if constexpr (!std::is_same_v<Archive, core::StateWriter>) {
      if (estimator_) {
        convoy::KeepOut keep_out = config_.teacher_keep_out;
        keep_out.obstacles = teacher_memory_.circles();
        estimator_->set_keep_out(std::move(keep_out));
      }
    }
  }
  a.end();
}

void ConvoyObservationBuilder::save_state(core::StateWriter& w) const {
  const_cast<ConvoyObservationBuilder*>(this)->state_io(w);  // the writer only reads
}

void ConvoyObservationBuilder::load_state(core::StateReader& r) { state_io(r); }

}  // namespace syndds::learn
