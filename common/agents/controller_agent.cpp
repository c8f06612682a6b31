#include "agents/controller_agent.hpp"

namespace syndds::agents {

ControllerAgent::ControllerAgent(const scenario::Scenario& scenario,
                                 const scenario::VehicleConfig& vehicle)
    : vehicle_id_(vehicle.id),
      member_id_(scenario::controller_member(vehicle.id)),
      follower_(control::Path(vehicle.controller.waypoints, vehicle.controller.closed),
                vehicle.controller.follower),
      stop_at_s_(vehicle.controller.stop_at_s) {}

std::vector<proto::Subscription> ControllerAgent::subscriptions() const {
  return {{proto::Topic::vehicle_state, vehicle_id_}};
}

void ControllerAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                           proto::FrameSamples& outputs) {
  for (const auto& state : inputs.vehicle_states) {
    if (state.vehicle_id != vehicle_id_) continue;
    auto cmd =
        follower_.update(state.sim_time_s, state.pose, state.linear_velocity, ctx.heartbeat_s);
    if (stop_at_s_ && state.sim_time_s >= *stop_at_s_) {
      cmd.throttle = 0.0;  // emergency stop: full brake from the first state at or after it
      cmd.braking = 1.0;
    }
    outputs.driver_commands.push_back(command_message(vehicle_id_, member_id_, ctx.frame, cmd));
  }
}

proto::DriverCommandMsg command_message(const std::string& vehicle_id, const std::string& source,
                                        std::int64_t frame, const vehicle::DriverInputs& inputs) {
  proto::DriverCommandMsg out;
  out.vehicle_id = vehicle_id;
  out.source = source;
  out.frame = frame;
  out.steering = inputs.steering;
  out.throttle = inputs.throttle;
  out.braking = inputs.braking;
  return out;
}

void ControllerAgent::save_state(core::StateWriter& w) { follower_.save_state(w); }

void ControllerAgent::load_state(core::StateReader& r) { follower_.load_state(r); }

}  // namespace syndds::agents
