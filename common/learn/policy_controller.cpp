#include "learn/policy_controller.hpp"

#include <ATen/Parallel.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <type_traits>

#include "agents/agent_factory.hpp"
#include "agents/controller_agent.hpp"
#include "core/error.hpp"
#include "learn/convoy_env.hpp"
#include "learn/registry.hpp"

namespace syndds::learn {
namespace {

std::string describe(const ObservationSpace& s) {
  std::string out = std::to_string(s.vector.size()) + " numbers";
  if (s.image) {
    out += " and a " + std::to_string(s.image->width) + " x " + std::to_string(s.image->height) +
           " image";
  }
  return out;
}

}  // namespace

namespace {

Policy load_policy(const std::string& file, const std::string& where) {
  // One thread: the same action in every process, whatever its thread pool would do.
  at::set_num_threads(1);
  Policy p;
  try {
    p.load(file);
  } catch (const std::exception& e) {
    throw ConfigError(where + "not a policy file (" + e.what() + ")");
  }
  return p;
}

// The environment options the policy was trained with: its file's env_options (a file
// without metadata is a convoy_follow policy on the defaults: the paper observation).
ConvoyEnvOptions policy_env_options(const Policy& policy, const std::string& where) {
  const auto& meta = policy.metadata();
  const auto env = meta.find("env");
  if (env != meta.end() && env->second != "convoy_follow") {
    throw ConfigError(where + "a policy of environment " + env->second +
                      ", not of convoy_follow: it cannot drive a convoy follower");
  }
  const auto options = meta.find("env_options");
  if (options == meta.end()) return ConvoyEnvOptions{};
  try {
    return convoy_env_options(parse_env_options_line(options->second));
  } catch (const std::invalid_argument& e) {
    throw ConfigError(where + "its env_options '" + options->second + "': " + e.what());
  }
}

// The vehicle's observation, with the camera only if the policy looks at one.
ConvoyObservationConfig observation_for(const scenario::Scenario& s,
                                        const scenario::VehicleConfig& v, const Policy& policy,
                                        const ConvoyEnvOptions& trained) {
  ConvoyObservationConfig c =
      convoy_observation_config(s, v, v.controller.convoy.leader, trained.observation);
  if (!policy.observation_space().image) c.image.reset();
  if (trained.observe_keep_out) {  // as ConvoyEnv::reset builds the driver's
    c.teacher_keep_out.clearance_m = trained.teacher_keep_clear_m;
    c.teacher_keep_out_perceived = true;
    c.observe_keep_out = true;
  }
  return c;
}

// The perception network of a policy that observes the keep-out (its metadata's
// "perception", relative to the policy file's directory).
std::shared_ptr<ppo::PerceptionModel> perception_for(const Policy& policy,
                                                     const std::string& policy_file,
                                                     const ConvoyEnvOptions& trained,
                                                     const std::string& where) {
  if (!trained.observe_keep_out) return nullptr;
  if (!trained.teacher_view_ranges || !policy.observation_space().image) {
    throw ConfigError(where + "the policy observes the trail shifted clear of obstacles (env "
                              "option observe_keep_out) from a map a controller does not have: "
                              "only a camera policy with teacher_view=ranges can drive");
  }
  const auto it = policy.metadata().find("perception");
  if (it == policy.metadata().end()) {
    throw ConfigError(where + "the policy observes the obstacles it perceives (observe_keep_out) "
                              "but names no perception network (metadata \"perception\")");
  }
  const std::filesystem::path file =
      std::filesystem::path(policy_file).parent_path() / it->second;
  try {
    auto model = std::make_shared<ppo::PerceptionModel>(ppo::PerceptionModel::load(file.string()));
    const ImageSpec& want = *policy.observation_space().image;
    if (model->image().width != want.width || model->image().height != want.height ||
        model->image().channels != want.channels || model->outputs() != kPerceptionRays) {
      throw ConfigError(where + "perception network " + file.string() + " reads another image "
                        "or gives another number of ranges than the policy's camera and " +
                        std::to_string(kPerceptionRays) + " rays");
    }
    return model;
  } catch (const std::runtime_error& e) {
    if (dynamic_cast<const ConfigError*>(&e)) throw;
    throw ConfigError(where + e.what());
  }
}

}  // namespace

PolicyControllerAgent::PolicyControllerAgent(const scenario::Scenario& s,
                                             const scenario::VehicleConfig& v)
    : vehicle_id_(v.id),
      leader_id_(v.controller.convoy.leader),
      member_id_(scenario::controller_member(v.id)),
      where_(s.file + ": vehicle " + v.id + ": controller.model " + v.controller.policy_file +
             ": "),
      policy_(load_policy(v.controller.policy_file, where_)),
      trained_(policy_env_options(policy_, where_)),
      builder_(observation_for(s, v, policy_, trained_)),
      perception_(perception_for(policy_, v.controller.policy_file, trained_, where_)) {
  const ObservationSpace expected = builder_.space();
  const ObservationSpace& got = policy_.observation_space();
  const bool same_image = expected.image.has_value() == got.image.has_value() &&
                          (!got.image || (got.image->width == expected.image->width &&
                                          got.image->height == expected.image->height &&
                                          got.image->channels == expected.image->channels));
  if (got.vector.size() != expected.vector.size() || !same_image) {
    throw ConfigError(where_ + "the policy observes " + describe(got) +
                      ", the vehicle's sensors give " + describe(expected) +
                      " (a camera policy needs the vehicle's first camera at its image size)");
  }
  if (perception_) {  // the camera the policy observes (checked above: it is there)
    const auto& camera = v.sensors->rig.cameras.front();
    camera_hfov_rad_ = camera.intrinsics.hfov_rad;
    camera_ahead_m_ = camera.mount.pose.position.x();
  }
  const std::size_t actions = convoy_action_space(trained_.observation).size();
  if (policy_.action_space().size() != actions) {
    throw ConfigError(where_ + "the policy has " + std::to_string(policy_.action_space().size()) +
                      " actions; a convoy follower on its observation has " +
                      std::to_string(actions) +
                      (actions == 2 ? " (steering, throttle/brake)"
                                    : " (steering, throttle/brake, memory)"));
  }
  // The scenario's period_s, else the policy's own: frames_per_step frames of the
  // environment's 0.01 s heartbeat.
  const double period_s = v.controller.policy_period_s > 0.0
                              ? v.controller.policy_period_s
                              : trained_.frames_per_step * kConvoyEnvHeartbeatS;
  const std::optional<std::int64_t> frames = scenario::whole_frames(period_s, s.time.heartbeat_s);
  if (!frames) {
    std::ostringstream msg;
    msg << where_ << "the policy acts every " << period_s
        << " s (its training period), not a whole multiple of time.heartbeat_s ("
        << s.time.heartbeat_s << " s): give controller.period_s";
    throw ConfigError(msg.str());
  }
  period_frames_ = *frames;
  action_period_s_ = period_frames_ * s.time.heartbeat_s;
}

std::vector<proto::Subscription> PolicyControllerAgent::subscriptions() const {
  return convoy_driver_subscriptions(vehicle_id_, leader_id_, builder_.config().estimator.trail_of);
}

void PolicyControllerAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                                 proto::FrameSamples& outputs) {
  // The observation as it stood after the previous frame (as the environment returns it).
  if (builder_.ready() && (actions_ == 0 || since_action_ >= period_frames_)) {
    const Observation seen = builder_.observation();
    const std::vector<float> a = policy_.act(seen, true);
    steering_ = convoy_lagged_steering(convoy_driver_inputs(steering_, 0.0).steering,
                                       convoy_steering_command(trained_, seen.vector, a[0]),
                                       trained_.steer_lag_s, action_period_s_);
    throttle_brake_ = a[1];
    builder_.note_action(steering_, throttle_brake_, a.size() > 2 ? a[2] : 0.0);
    if (perception_) {
      const std::vector<float> ranges = perception_->read(seen.image);
      builder_.observe_ranges({ranges, camera_hfov_rad_, kPerceptionRangeM, camera_ahead_m_});
    }
    since_action_ = 0;
    ++actions_;
  }
  builder_.consume(ctx, inputs);
  outputs.driver_commands.push_back(agents::command_message(
      vehicle_id_, member_id_, ctx.frame, convoy_driver_inputs(steering_, throttle_brake_)));
  ++since_action_;
}

template <typename Archive>
void PolicyControllerAgent::state_io(Archive& a) {
  a.begin("policy_controller", 1);
  if constexpr (std::is_same_v<Archive, core::StateWriter>) {
    builder_.save_state(a);
  } else {
    builder_.load_state(a);
  }
  a.io(since_action_);
  a.io(actions_);
  a.io(steering_);
  a.io(throttle_brake_);
  a.end();
}

void PolicyControllerAgent::save_state(core::StateWriter& w) { state_io(w); }

void PolicyControllerAgent::load_state(core::StateReader& r) { state_io(r); }

void register_policy_controller() {
  agents::register_controller_type(
      "policy", [](const scenario::Scenario& s, const scenario::VehicleConfig& v) {
        return std::make_unique<PolicyControllerAgent>(s, v);
      });
}

}  // namespace syndds::learn
