#include "agents/controller_agent.hpp"

namespace syndds::agents {

ControllerAgent::ControllerAgent(const scenario::Scenario& scenario,
                                 const scenario::VehicleConfig& vehicle)
    : vehicle_id_(vehicle.id),
      member_id_(scenario::controller_member(vehicle.id)),
      follower_(control::Path(vehicle.controller.waypoints, vehicle.controller.closed),
                vehicle.controller.follower) {}

std::vector<proto::Subscription> ControllerAgent::subscriptions() const {
  return {{proto::Topic::vehicle_state, vehicle_id_}};
}

void ControllerAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                           proto::FrameSamples& outputs) {
  for (const auto& state : inputs.vehicle_states) {
    if (state.vehicle_id != vehicle_id_) continue;
    const auto cmd =
        follower_.update(state.sim_time_s, state.pose, state.linear_velocity, ctx.heartbeat_s);
    proto::DriverCommandMsg out;
    out.vehicle_id = vehicle_id_;
    out.source = member_id_;
    out.frame = ctx.frame;
    out.steering = cmd.steering;
    out.throttle = cmd.throttle;
    out.braking = cmd.braking;
    outputs.driver_commands.push_back(out);
  }
}

}  // namespace syndds::agents
