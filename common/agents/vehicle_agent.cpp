#include "agents/vehicle_agent.hpp"

#include <spdlog/spdlog.h>

#include <cmath>

#include "core/error.hpp"
#include "vehicle/bicycle_model.hpp"
#include "vehicle/ode_vehicle.hpp"

namespace syndds::agents {

std::unique_ptr<vehicle::VehicleModel> make_vehicle_model(const scenario::Scenario& s,
                                                          const scenario::VehicleConfig& config) {
  auto terrain = scenario::make_terrain(s.terrain);
  if (config.dynamics == "reduced") {
    return std::make_unique<vehicle::BicycleModel>(config.params, config.start, std::move(terrain));
  }
  if (config.dynamics == "full") {
    return std::make_unique<vehicle::OdeVehicleModel>(config.params, config.start,
                                                      std::move(terrain), s.obstacles);
  }
  throw ConfigError("vehicle '" + config.id + "': unknown dynamics '" + config.dynamics + "'");
}

std::string validate_command(const proto::DriverCommandMsg& cmd) {
  auto check = [](const char* name, double v, double lo, double hi) -> std::string {
    if (!std::isfinite(v)) return std::string(name) + " is not a finite number";
    if (v < lo || v > hi) {
      return std::string(name) + " = " + std::to_string(v) + " is outside [" +
             std::to_string(lo) + ", " + std::to_string(hi) + "]";
    }
    return "";
  };
  for (const auto& err : {check("steering", cmd.steering, -1, 1),
                          check("throttle", cmd.throttle, 0, 1),
                          check("braking", cmd.braking, 0, 1)}) {
    if (!err.empty()) return err;
  }
  return "";
}

VehicleAgent::VehicleAgent(const scenario::Scenario& scenario,
                           const scenario::VehicleConfig& vehicle)
    : vehicle_id_(vehicle.id),
      member_id_(scenario::vehicle_member(vehicle.id)),
      step_s_(scenario.time.step_s),
      steps_per_frame_(scenario.time.steps_per_frame()),
      model_(make_vehicle_model(scenario, vehicle)) {}

std::vector<proto::Subscription> VehicleAgent::subscriptions() const {
  return {{proto::Topic::driver_command, vehicle_id_}};
}

void VehicleAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                        proto::FrameSamples& outputs) {
  // The newest valid command stamped k-1 (several writers: the last in canonical order wins).
  for (const auto& cmd : inputs.driver_commands) {
    const std::string error = validate_command(cmd);
    if (!error.empty()) {
      ++rejected_;
      spdlog::error("{}: rejected driver_command from {} stamped frame {}: {}", member_id_,
                    cmd.source, cmd.frame, error);
      continue;
    }
    model_->set_inputs({cmd.steering, cmd.throttle, cmd.braking});
  }
  if (ctx.frame > 0) {
    for (std::int64_t i = 0; i < steps_per_frame_; ++i) model_->advance(step_s_);
  }
  outputs.vehicle_states.push_back(state_message(ctx.frame, ctx.sim_time_s));
  for (const auto& c : model_->take_collisions()) {
    proto::CollisionEventMsg e;
    e.vehicle_id = vehicle_id_;
    e.source = member_id_;
    e.frame = ctx.frame;
    e.sim_time_s = ctx.sim_time_s;
    e.obstacle_id = c.obstacle_id;
    e.impulse_ns = c.impulse_ns;
    e.position = c.position;
    outputs.collision_events.push_back(std::move(e));
  }
}

proto::VehicleStateMsg VehicleAgent::state_message(std::int64_t frame, double sim_time_s) const {
  const vehicle::VehicleSnapshot s = model_->snapshot();
  proto::VehicleStateMsg m;
  m.vehicle_id = vehicle_id_;
  m.source = member_id_;
  m.frame = frame;
  m.sim_time_s = sim_time_s;
  m.pose = s.pose;
  m.linear_velocity = s.linear_velocity;
  m.angular_velocity = s.angular_velocity;
  m.linear_acceleration = s.linear_acceleration;
  m.angular_acceleration = s.angular_acceleration;
  for (const auto& w : s.wheels) {
    m.wheels.push_back({w.pose, w.spin_rad_s, w.steer_angle_rad, w.vertical_load_n});
  }
  m.steering = s.inputs.steering;
  m.throttle = s.inputs.throttle;
  m.braking = s.inputs.braking;
  m.gear = s.gear;
  m.engine_speed_rpm = s.engine_speed_rpm;
  return m;
}

}  // namespace syndds::agents
