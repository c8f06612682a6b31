#include "learn/convoy_env.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "agents/agent_factory.hpp"
#include "agents/controller_agent.hpp"
#include "agents/sensor_agent.hpp"
#include "core/yaml.hpp"
#include "sensors/scene.hpp"

namespace syndds::learn {
namespace {

// Does the chassis box's footprint (a rectangle) of `state` overlap the obstacle's circle?
bool footprint_hits(const proto::VehicleStateMsg& state, const vehicle::ChassisParams& chassis,
                    const ConvoyObstacle& ob) {
  const double yaw = yaw_of(state.pose.orientation);
  const Vec2 rel(ob.centre.x() - state.pose.position.x(), ob.centre.y() - state.pose.position.y());
  // The obstacle's centre in the vehicle frame, relative to the box centre.
  const double lx = std::cos(yaw) * rel.x() + std::sin(yaw) * rel.y() - chassis.box_centre_m.x();
  const double ly = -std::sin(yaw) * rel.x() + std::cos(yaw) * rel.y() - chassis.box_centre_m.y();
  const double hx = chassis.half_extents_m.x(), hy = chassis.half_extents_m.y();
  const double dx = std::max(std::abs(lx) - hx, 0.0), dy = std::max(std::abs(ly) - hy, 0.0);
  return dx * dx + dy * dy < ob.radius_m * ob.radius_m;
}

// The first uniform draw in [0, 1) of episode `seed`'s stream `stream`: each per-episode draw
// of the options has a stream of its own, so that adding one changes none of the others (nor
// those of make_convoy_episode).
double episode_uniform(std::uint64_t seed, std::uint64_t stream) {
  std::mt19937_64 rng(seed ^ stream);
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

}  // namespace

double convoy_reward(double distance_m, double heading_diff_rad, const ConvoyRewardParams& p) {
  if (std::abs(heading_diff_rad) > p.heading_window_rad) return p.outside;
  return 1.0 / (1.0 + std::abs(distance_m - p.optimal_gap_m) / p.width_m);
}

double convoy_track_reward(double distance_m, double path_error_m, const ConvoyRewardParams& p) {
  return 1.0 / (1.0 + std::abs(distance_m - p.optimal_gap_m) / p.width_m) /
         (1.0 + std::abs(path_error_m) / p.track_width_m);
}

// ---- ConvoyDriverAgent ----------------------------------------------------------------------

ConvoyDriverAgent::ConvoyDriverAgent(const scenario::Scenario& scenario,
                                     const scenario::VehicleConfig& follower,
                                     const std::string& leader_id, ConvoyObservationKind kind,
                                     const convoy::KeepOut& teacher_keep_out,
                                     bool teacher_keep_out_perceived, bool observe_keep_out)
    : vehicle_id_(follower.id),
      leader_id_(leader_id),
      member_id_(scenario::external_member(follower.id)),
      builder_([&] {
        ConvoyObservationConfig c = convoy_observation_config(scenario, follower, leader_id, kind);
        c.teacher_keep_out = teacher_keep_out;
        c.teacher_keep_out_perceived = teacher_keep_out_perceived;
        c.observe_keep_out = observe_keep_out;
        return c;
      }()) {}

ConvoyScenarioOptions convoy_scenario_options(const ConvoyEnvOptions& options, std::uint64_t seed) {
  ConvoyScenarioOptions so;
  so.terrain = options.terrain;
  so.dynamics = options.dynamics;
  so.camera = options.camera;
  so.target_speed_mps = options.target_speed_mps;
  if (options.target_speed_max_mps > options.target_speed_mps) {
    const double u = episode_uniform(seed, 0x5eed5eed5eed5eedULL);
    so.target_speed_mps = options.target_speed_mps +
                          u * (options.target_speed_max_mps - options.target_speed_mps);
  }
  so.end_time_s = kConvoyEnvHeartbeatS * options.frames_per_step * (options.max_steps + 100);
  so.seed = seed;
  if (options.random_ground_colour) so.ground_colour = convoy_ground_colour(seed);
  if (options.friction_min > 0.0) so.friction = convoy_ground_friction(seed, options.friction_min);
  return so;
}

double convoy_start_hold(std::uint64_t seed, double hold_max_s) {
  return hold_max_s * episode_uniform(seed, 0x401d401d401d401dULL);
}

double convoy_ground_friction(std::uint64_t seed, double friction_min) {
  constexpr double kRigidFriction = 0.8;
  return friction_min +
         episode_uniform(seed, 0xf41c7104f41c7104ULL) * (kRigidFriction - friction_min);
}

std::array<double, 3> convoy_ground_colour(std::uint64_t seed) {
  std::mt19937_64 rng(seed ^ 0xc0104c0104c0104cULL);
  auto uniform = [&rng] { return static_cast<double>(rng() >> 11) * 0x1.0p-53; };
  const sensors::Rgb grey = sensors::terrain_look("rigid").colour;
  const sensors::Rgb brown = sensors::terrain_look("silt").colour;
  const double share = uniform();
  const double brightness = 0.7 + 0.6 * uniform();
  auto mix = [&](float a, float b) {
    return std::clamp(brightness * ((1.0 - share) * a + share * b), 0.0, 1.0);
  };
  return {mix(grey.r, brown.r), mix(grey.g, brown.g), mix(grey.b, brown.b)};
}

double convoy_steering_command(const ConvoyEnvOptions& options, std::span<const float> seen,
                               double action) {
  if (!options.steering_residual) return action;
  if (seen.size() <= kFeedforwardIndex) {
    throw std::invalid_argument("convoy_steering_command: the observation has no feed-forward "
                                "steering");
  }
  return seen[kFeedforwardIndex] + action;
}

vehicle::DriverInputs convoy_driver_inputs(double steering, double throttle_brake) {
  const double s = std::isnan(steering) ? 0.0 : std::clamp(steering, -1.0, 1.0);
  const double p = std::isnan(throttle_brake) ? 0.0 : std::clamp(throttle_brake, -1.0, 1.0);
  vehicle::DriverInputs cmd;
  cmd.steering = s;
  cmd.throttle = std::max(p, 0.0);
  cmd.braking = std::max(-p, 0.0);
  return cmd;
}

double convoy_lagged_steering(double previous, double action, double lag_s, double period_s) {
  const double target = std::isnan(action) ? 0.0 : std::clamp(action, -1.0, 1.0);
  if (lag_s <= 0.0) return target;
  return previous + (1.0 - std::exp(-period_s / lag_s)) * (target - previous);
}

std::vector<float> convoy_heuristic_action(const Observation& o) {
  if (o.vector.size() != 4) {
    throw std::invalid_argument("the hand-written follower reads the paper observation (4 "
                                "numbers), not " + std::to_string(o.vector.size()));
  }
  const double north = o.vector.at(0), east = o.vector.at(1), heading = o.vector.at(2);
  const double closing = o.vector.at(3);
  const double bearing = std::atan2(east, north);    // clockwise from north, as the compass
  const double off = wrap_angle(bearing - heading);  // > 0: the leader is to the right
  const double gap = std::hypot(north, east);
  const double steer = std::clamp(-2.0 * off, -1.0, 1.0);  // steering > 0 turns left
  const double pedal = std::clamp(0.15 * (gap - 15.0) - 0.3 * closing, -1.0, 1.0);
  return {static_cast<float>(steer), static_cast<float>(pedal)};
}

std::vector<proto::Subscription> convoy_driver_subscriptions(const std::string& vehicle_id,
                                                             const std::string& leader_id,
                                                             const std::string& trail_of) {
  std::vector<proto::Subscription> subs = {{proto::Topic::gps_fix, vehicle_id},
                                           {proto::Topic::magnetometer, vehicle_id},
                                           {proto::Topic::wheel_speeds, vehicle_id},
                                           {proto::Topic::image, vehicle_id},
                                           {proto::Topic::v2v_message, leader_id}};
  if (!trail_of.empty() && trail_of != leader_id) subs.push_back({proto::Topic::v2v_message, trail_of});
  return subs;
}

std::vector<proto::Subscription> ConvoyDriverAgent::subscriptions() const {
  return convoy_driver_subscriptions(vehicle_id_, leader_id_);
}

void ConvoyDriverAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                             proto::FrameSamples& outputs) {
  builder_.consume(ctx, inputs);
  outputs.driver_commands.push_back(agents::command_message(
      vehicle_id_, member_id_, ctx.frame, convoy_driver_inputs(steering_, throttle_brake_)));
}

void ConvoyDriverAgent::set_action(double steering, double throttle_brake, double memory) {
  steering_ = steering;  // clamped when written (convoy_driver_inputs)
  throttle_brake_ = throttle_brake;
  builder_.note_action(steering, throttle_brake, memory);
}

// ---- ConvoyEnv ------------------------------------------------------------------------------

ConvoyEnv::ConvoyEnv(ConvoyEnvOptions options) : options_(std::move(options)) {
  if (options_.config_dir.empty()) options_.config_dir = scenario::default_config_dir();
  if (options_.frames_per_step < 1 || options_.max_steps < 1) {
    throw std::invalid_argument("ConvoyEnv: frames_per_step and max_steps must be >= 1");
  }
  if (options_.random_ground_colour && options_.terrain != ConvoyTerrain::rigid) {
    throw std::invalid_argument("ConvoyEnv: random_ground_colour needs the rigid terrain (the "
                                "soils keep their own look)");
  }
  if ((options_.teacher_view_camera || options_.teacher_view_ranges) && !options_.camera) {
    throw std::invalid_argument("ConvoyEnv: teacher_view_camera and _ranges need the camera");
  }
  if (options_.observe_keep_out && !(options_.teacher_keep_clear_m > 0.0)) {
    throw std::invalid_argument("ConvoyEnv: observe_keep_out needs teacher_keep_clear_m > 0");
  }
  if (options_.teacher_view_camera && options_.teacher_view_ranges) {
    throw std::invalid_argument("ConvoyEnv: teacher_view is camera or ranges, not both");
  }
  if (options_.steering_residual && !has_feedforward(options_.observation)) {
    throw std::invalid_argument("ConvoyEnv: steering_residual needs an observation with the "
                                "feed-forward steering (trail_ff, trail_ff_memory)");
  }
  if (options_.friction_min != 0.0 &&
      (options_.terrain != ConvoyTerrain::rigid || !(options_.friction_min > 0.0) ||
       options_.friction_min > 0.8)) {
    throw std::invalid_argument("ConvoyEnv: friction_min is for the rigid terrain, in (0, 0.8]");
  }
}

ConvoyEnv::~ConvoyEnv() = default;

ObservationSpace ConvoyEnv::observation_space() const {
  ObservationSpace s{ConvoyObservationBuilder::vector_space(options_.observation), std::nullopt};
  if (options_.camera) s.image = ImageSpec{80, 45, 3};
  return s;
}

Box ConvoyEnv::action_space() const { return convoy_action_space(options_.observation); }

void ConvoyEnv::run_frame() {
  stepper_->step();
  const proto::FrameSamples& out = stepper_->last_outputs();
  for (const auto& s : out.vehicle_states) {
    if (s.vehicle_id == kConvoyFollowerId) follower_state_ = s;
    if (s.vehicle_id == kConvoyLeaderId) leader_state_ = s;
    if (s.vehicle_id == kConvoyHeadId) head_state_ = s;
  }
  for (const auto& c : out.collision_events) {
    if (c.vehicle_id != kConvoyFollowerId) continue;
    // Running into the leader is a collision like any other (docs/vehicle-contact.md).
    collided_ = true;
    leader_contact_ = leader_contact_ || c.other_vehicle_id == kConvoyLeaderId;
  }
  // The reduced model passes through obstacles without contacts: test its chassis footprint.
  const auto& chassis = scenario_->find_vehicle(kConvoyFollowerId)->params.chassis;
  for (const auto& ob : episode_.obstacles) {
    collided_ = collided_ || footprint_hits(follower_state_, chassis, ob);
  }
}

Observation ConvoyEnv::reset(std::uint64_t seed) {
  running_ = false;
  driver_ = nullptr;
  sensor_ = nullptr;
  stepper_.reset();
  episode_ = make_convoy_episode(seed, options_.episode);
  const std::string yaml = convoy_scenario_yaml(episode_, convoy_scenario_options(options_, seed));
  const std::string name = options_.config_dir + "/scenarios/convoy_env.yaml";
  scenario_.emplace(scenario::parse_scenario(YamlNode::load_string(yaml, name), yaml, {},
                                             options_.config_dir));
  const scenario::Scenario& s = *scenario_;

  std::vector<proto::AgentPtr> agents;
  const record::RecorderOptions no_recorder;
  for (const auto& m : s.member_ids()) {
    if (m == scenario::external_member(kConvoyFollowerId)) {
      convoy::KeepOut keep_out;
      if (options_.teacher_keep_clear_m > 0.0) {
        keep_out.clearance_m = options_.teacher_keep_clear_m;
        if (!options_.teacher_view_ranges) {
          for (const auto& ob : episode_.obstacles) keep_out.obstacles.push_back({ob.centre, ob.radius_m});
        }
        if (options_.teacher_view_camera) {
          const auto& follower = *s.find_vehicle(kConvoyFollowerId);
          const auto& camera = follower.sensors->rig.cameras.front();
          keep_out.view_half_angle_rad = 0.5 * camera.intrinsics.hfov_rad;
          keep_out.view_ahead_m = camera.mount.pose.position.x();
        }
      }
      auto d = std::make_unique<ConvoyDriverAgent>(s, *s.find_vehicle(kConvoyFollowerId),
                                                   kConvoyLeaderId, options_.observation, keep_out,
                                                   options_.teacher_view_ranges,
                                                   options_.observe_keep_out);
      driver_ = d.get();
      agents.push_back(std::move(d));
    } else if (m == scenario::sensor_member(kConvoyFollowerId)) {
      // Renders only: the rig saves no frames, so no output directory is needed.
      agents::SensorAgentOptions so;
      so.commit_only_to_render = options_.render_only_observed;
      auto sensor = std::make_unique<agents::SensorAgent>(s, *s.find_vehicle(kConvoyFollowerId), so);
      sensor_ = sensor.get();
      agents.push_back(std::move(sensor));
    } else {
      agents.push_back(agents::make_agent(s, m, no_recorder));
    }
  }
  stepper_ = std::make_unique<proto::FrameStepper>(std::move(agents), s.time.heartbeat_s);
  collided_ = false;
  leader_contact_ = false;
  last_steering_ = 0.0;
  steps_ = 0;
  follower_state_ = {};
  leader_state_ = {};
  head_state_ = {};
  // Frames until every input of the observation has arrived (the first GPS fix and V2V
  // message, lagged 0.1 s, and the first camera frame): the follower holds its brake.
  driver_->set_action(0.0, -1.0);
  for (int k = 0; !driver_->observations().ready(); ++k) {
    if (k > 100 * options_.frames_per_step) {
      throw std::runtime_error("ConvoyEnv: the observation is incomplete after " +
                               std::to_string(k) + " frames");
    }
    run_frame();
  }
  // start_hold_max_s: the leader drives off while the follower waits, braked, on its trail.
  if (options_.start_hold_max_s > 0.0) {
    const auto hold_frames = static_cast<std::int64_t>(std::llround(
        convoy_start_hold(seed, options_.start_hold_max_s) / scenario_->time.heartbeat_s));
    for (std::int64_t k = 0; k < hold_frames && !collided_; ++k) run_frame();
  }
  running_ = true;
  if (sensor_ && options_.render_only_observed) {
    // From here on the policy reads the observation after every frames_per_step frames: after
    // frame D = first + fps j (j >= 0). It holds the newest camera frame the driver agent has
    // consumed by then, one available at tick A <= D - 2 (the sensor agent publishes it in frame
    // A + 1, stamped A + 1, the driver reads it in frame A + 2). A frame is made only if some
    // D - 2 falls in [its available tick, the next frame's): the one the policy will see.
    const std::int64_t first = stepper_->next_frame() - 1;
    const std::int64_t fps = options_.frames_per_step;
    sensor_->set_camera_frame_filter([first, fps](std::int64_t available, std::int64_t next) {
      const std::int64_t base = first - 2;  // D - 2 for j = 0
      const std::int64_t j = available <= base ? 0 : (available - base + fps - 1) / fps;
      return base + fps * j < next;
    });
  }
  Observation o = driver_->observations().observation();
  seen_ = o.vector;
  return o;
}

StepResult ConvoyEnv::step(std::span<const float> action) {
  if (!running_) throw std::logic_error("ConvoyEnv::step before reset or after the episode ended");
  const std::size_t expected = action_space().size();
  if (action.size() != expected) {
    throw std::invalid_argument("ConvoyEnv::step: expected " + std::to_string(expected) +
                                " action values, got " + std::to_string(action.size()));
  }
  const double period_s = options_.frames_per_step * scenario_->time.heartbeat_s;
  const double command = convoy_steering_command(options_, seen_, action[0]);
  const double steering = convoy_lagged_steering(
      convoy_driver_inputs(driver_->steering(), 0.0).steering, command, options_.steer_lag_s,
      period_s);
  driver_->set_action(steering, action[1], expected > 2 ? action[2] : 0.0);
  if (options_.teacher_view_ranges && options_.teacher_keep_clear_m > 0.0) {
    const std::vector<float> ranges = options_.perceive_ranges
                                          ? options_.perceive_ranges(driver_->observations().observation())
                                          : perception_target();
    const auto& camera = scenario_->find_vehicle(kConvoyFollowerId)->sensors->rig.cameras.front();
    driver_->observe_ranges({ranges, camera.intrinsics.hfov_rad, kPerceptionRangeM,
                             camera.mount.pose.position.x()});
  }
  for (int f = 0; f < options_.frames_per_step && !collided_; ++f) run_frame();
  ++steps_;

  StepResult r;
  r.observation = driver_->observations().observation();
  seen_ = r.observation.vector;
  const Vec3 rel = leader_state_.pose.position - follower_state_.pose.position;
  const double distance = std::hypot(rel.x(), rel.y());
  const double heading_diff =
      wrap_angle(std::atan2(rel.y(), rel.x()) - yaw_of(follower_state_.pose.orientation));
  const double speed = std::hypot(follower_state_.linear_velocity.x(),
                                  follower_state_.linear_velocity.y());
  const double leader_speed =
      std::hypot(leader_state_.linear_velocity.x(), leader_state_.linear_velocity.y());
  // Done when the path follower at the convoy's head has stopped at the path's end and the
  // leader has stopped too (in an unchained episode they are the same vehicle).
  const Vec2 end = episode_.path.back();
  const proto::VehicleStateMsg& head = episode_.chained ? head_state_ : leader_state_;
  const bool leader_done =
      std::hypot(head.pose.position.x() - end.x(), head.pose.position.y() - end.y()) < 3.0 &&
      std::hypot(head.linear_velocity.x(), head.linear_velocity.y()) < 0.1 && leader_speed < 0.1;
  const bool lost = distance > options_.lost_distance_m;
  const Vec2 here(follower_state_.pose.position.x(), follower_state_.pose.position.y());
  const double path_error = distance_to_path(episode_.path, here);
  if (collided_) {
    r.reward = options_.reward.collision;
    r.terminated = true;
  } else if (lost) {
    r.reward = options_.reward.lost;
    r.terminated = true;
  } else {
    if (options_.reward_kind == ConvoyRewardKind::track) {
      const double change = steering - last_steering_;
      r.reward = convoy_track_reward(distance, path_error, options_.reward) -
                 options_.reward.steer_change * change * change;
    } else {
      r.reward = convoy_reward(distance, heading_diff, options_.reward);
    }
    r.truncated = leader_done || steps_ >= options_.max_steps;
  }
  r.info = {{"distance_m", distance},
            {"heading_diff_rad", heading_diff},
            {"speed_mps", speed},
            {"leader_speed_mps", leader_speed},
            {"path_error_m", path_error},
            {"collided", collided_ ? 1.0 : 0.0},
            {"leader_contact", leader_contact_ ? 1.0 : 0.0},
            {"leader_lost", lost ? 1.0 : 0.0},
            {"leader_done", leader_done ? 1.0 : 0.0},
            {"steps", static_cast<double>(steps_)}};
  last_steering_ = steering;
  running_ = !(r.terminated || r.truncated);
  return r;
}

std::vector<float> ConvoyEnv::expert_action() const {
  if (!driver_) return {};
  const ConvoyObservationBuilder& built = driver_->observations();
  std::vector<float> a = built.classical_action();
  for (float& v : a) v = std::clamp(v, -1.0f, 1.0f);
  if (a.empty()) return a;
  const auto limit = static_cast<float>(options_.teacher_steering_limit);
  if (limit > 1.0f) {
    a[0] = std::clamp(static_cast<float>(built.classical_steering_beyond_lock()), -limit, limit);
  }
  // The command minus what the action is added to (0 unless steering_residual).
  a[0] = std::clamp(a[0] - static_cast<float>(convoy_steering_command(options_, seen_, 0.0)),
                    -limit, limit);
  return a;
}

std::vector<float> obstacle_ranges(const Vec2& camera, double yaw_rad, double hfov_rad, int rays,
                                   double range_m, std::span<const ConvoyObstacle> obstacles) {
  if (rays < 1 || !(range_m > 0.0) || !(hfov_rad > 0.0)) {
    throw std::invalid_argument("obstacle_ranges: needs rays >= 1, a range and a field of view > 0");
  }
  std::vector<float> out(static_cast<std::size_t>(rays), 1.0f);
  const double slice = hfov_rad / rays;
  for (int k = 0; k < rays; ++k) {
    const double bearing = yaw_rad + 0.5 * hfov_rad - (k + 0.5) * slice;
    const Vec2 d(std::cos(bearing), std::sin(bearing));
    double nearest = range_m;
    for (const auto& ob : obstacles) {
      // |camera + t d - centre| = radius: t^2 - 2 b t + c = 0 with b = d.(centre - camera).
      const Vec2 to = ob.centre - camera;
      const double c = to.squaredNorm() - ob.radius_m * ob.radius_m;
      if (c <= 0.0) {
        nearest = 0.0;
        break;
      }
      const double b = d.dot(to);
      const double disc = b * b - c;
      if (b <= 0.0 || disc < 0.0) continue;  // behind the camera, or missed
      nearest = std::min(nearest, b - std::sqrt(disc));
    }
    out[static_cast<std::size_t>(k)] = static_cast<float>(std::min(nearest / range_m, 1.0));
  }
  return out;
}

std::vector<float> ConvoyEnv::perception_target() const {
  if (!options_.camera || !scenario_) return {};
  const auto& camera = scenario_->find_vehicle(kConvoyFollowerId)->sensors->rig.cameras.front();
  const double yaw = yaw_of(follower_state_.pose.orientation);
  const Vec2 heading(std::cos(yaw), std::sin(yaw)), left(-std::sin(yaw), std::cos(yaw));
  const Vec3& mount = camera.mount.pose.position;
  const Vec2 at = Vec2(follower_state_.pose.position.x(), follower_state_.pose.position.y()) +
                  mount.x() * heading + mount.y() * left;
  return obstacle_ranges(at, yaw, camera.intrinsics.hfov_rad, kPerceptionRays, kPerceptionRangeM,
                         episode_.obstacles);
}

std::unique_ptr<Env> make_convoy_env(const ConvoyEnvOptions& options) {
  return std::make_unique<ConvoyEnv>(options);
}

}  // namespace syndds::learn
