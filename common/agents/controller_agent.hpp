#pragma once
// The path-following controller member: reads its vehicle's state stamped k-1 and publishes
// the DriverCommand stamped k (applied by the vehicle in frame k+1: one frame of latency).
#include <optional>

#include "control/path_follower.hpp"
#include "protocol/agent.hpp"
#include "scenario/scenario.hpp"

namespace syndds::agents {

/// The DriverCommand a controller member publishes for `inputs`.
proto::DriverCommandMsg command_message(const std::string& vehicle_id, const std::string& source,
                                        std::int64_t frame, const vehicle::DriverInputs& inputs);

class ControllerAgent final : public proto::Agent {
 public:
  ControllerAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& vehicle);

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::controller; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override { return {proto::Topic::driver_command}; }
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;

  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  const control::PathFollower& follower() const { return follower_; }

 private:
  std::string vehicle_id_;
  std::string member_id_;
  control::PathFollower follower_;
  std::optional<double> stop_at_s_;  // full brake from then on (controller.stop_at_s)
};

}  // namespace syndds::agents
