#pragma once
// The vehicle member: owns one dynamics model, applies the DriverCommand stamped k-1, steps
// steps_per_frame dynamics steps in frame k and publishes its VehicleState stamped k.
#include <memory>

#include "protocol/agent.hpp"
#include "scenario/scenario.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::agents {

/// Builds the dynamics model a vehicle entry of the scenario asks for, on the scenario's terrain
/// and among its obstacles.
std::unique_ptr<vehicle::VehicleModel> make_vehicle_model(const scenario::Scenario& scenario,
                                                          const scenario::VehicleConfig& config);

/// Checks a received command; returns an empty string if valid, else which field is wrong.
std::string validate_command(const proto::DriverCommandMsg& cmd);

class VehicleAgent final : public proto::Agent {
 public:
  VehicleAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& vehicle);

  const std::string& member_id() const override { return member_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::vehicle; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override { return {proto::Topic::vehicle_state, proto::Topic::collision_event}; }
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;

  const vehicle::VehicleModel& model() const { return *model_; }
  std::uint64_t rejected_commands() const { return rejected_; }

 private:
  proto::VehicleStateMsg state_message(std::int64_t frame, double sim_time_s) const;

  std::string vehicle_id_;
  std::string member_id_;
  double step_s_;
  std::int64_t steps_per_frame_;
  std::unique_ptr<vehicle::VehicleModel> model_;
  std::uint64_t rejected_ = 0;
};

}  // namespace syndds::agents
