#pragma once
// A minimal external driver: once it sees its vehicle's state it sends the same command every
// frame. It plays the "external/<id>" member of a scenario whose vehicle has
// `controller: {type: external}`, and serves as the worked example of docs/protocol.md.
#include "protocol/agent.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::agents {

class ConstantDriverAgent final : public proto::Agent {
 public:
  ConstantDriverAgent(std::string member_id, std::string vehicle_id, vehicle::DriverInputs command)
      : member_id_(std::move(member_id)), vehicle_id_(std::move(vehicle_id)), command_(command) {}

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::external; }
  std::vector<proto::Subscription> subscriptions() const override {
    return {{proto::Topic::vehicle_state, vehicle_id_}};
  }
  std::vector<proto::Topic> publications() const override { return {proto::Topic::driver_command}; }
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override {
    if (inputs.vehicle_states.empty()) return;
    proto::DriverCommandMsg c;
    c.vehicle_id = vehicle_id_;
    c.source = member_id_;
    c.frame = ctx.frame;
    c.steering = command_.steering;
    c.throttle = command_.throttle;
    c.braking = command_.braking;
    outputs.driver_commands.push_back(c);
  }
  // Nothing changes between frames; the section still checks that a state belongs here.
  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override {
    w.begin("constant_driver", 1);
    w.end();
  }
  void load_state(core::StateReader& r) override {
    r.begin("constant_driver", 1);
    r.end();
  }

 private:
  std::string member_id_;
  std::string vehicle_id_;
  vehicle::DriverInputs command_;
};

}  // namespace syndds::agents
