#pragma once
// The learned-policy controller member (`controller: {type: policy, model: FILE, follow: ID}`):
// a convoy follower driven by a policy trained on the convoy-follow environment, from the same
// observation built from the same samples (its vehicle's GPS, compass, tachometer and camera,
// the followed vehicle's V2V) with the same timing: until every input has arrived it holds
// the brake; then, in the frame after the observation is complete and every `period_s` after
// (0.1 s, the environment's control period), it takes the policy's deterministic action from
// the observation as it stood after the previous frame, and writes it as its DriverCommand
// every frame. Inference runs on one thread, so every process computes the same actions.
// A policy trained to keep clear of what its camera shows (env options observe_keep_out and
// teacher_view=ranges) comes with a perception network (metadata "perception": a file beside
// the policy); after each action the controller gives the network's reading of the image the
// policy saw to the observation's obstacle memory, as the environment does.
#include <cstdint>
#include <string>

#include "learn/convoy_env.hpp"
#include "learn/ppo/perception_model.hpp"
#include "learn/ppo/policy.hpp"
#include "learn/register_policy_controller.hpp"
#include "protocol/agent.hpp"
#include "scenario/scenario.hpp"

namespace syndds::learn {

class PolicyControllerAgent final : public proto::Agent {
 public:
  /// Loads the policy file and checks it against the vehicle's sensors; ConfigError naming the
  /// scenario file, the vehicle and the policy file if it does not fit. A low-dimensional
  /// policy ignores the vehicle's cameras (e.g. a chase camera for the video); a camera policy
  /// observes the vehicle's first camera, which must have the policy's image size.
  PolicyControllerAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& vehicle);

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::controller; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override { return {proto::Topic::driver_command}; }
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;

  /// Checkpoints: the readings the observation is built from, the action held and when the
  /// next one is due (the policy itself is the file's, and acts deterministically).
  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  /// Actions taken so far (one per control period once the observation was complete).
  std::uint64_t actions_taken() const { return actions_; }

 private:
  /// The one description of the checkpointed state, for writing and for reading.
  template <typename Archive>
  void state_io(Archive& a);

  std::string vehicle_id_;
  std::string leader_id_;
  std::string member_id_;
  std::string where_;  // "<scenario>: vehicle <id>: controller.model <file>: " for errors
  Policy policy_;      // loaded before the builder: it says whether the camera is observed
  ConvoyEnvOptions trained_;  // the environment options of its training (metadata)
  ConvoyObservationBuilder builder_;
  // A policy trained with observe_keep_out and teacher_view=ranges: the perception network
  // that reads the obstacles' ranges from the camera's image (the policy's metadata
  // "perception", a file beside the policy), and where that camera is.
  std::shared_ptr<ppo::PerceptionModel> perception_;
  double camera_hfov_rad_ = 0.0;
  double camera_ahead_m_ = 0.0;
  std::int64_t period_frames_ = 10;
  double action_period_s_ = 0.1;
  std::int64_t since_action_ = 0;
  std::uint64_t actions_ = 0;
  double steering_ = 0.0;          // as applied (after the steering lag of the training)
  double throttle_brake_ = -1.0;  // the brake until the first action
};

}  // namespace syndds::learn
