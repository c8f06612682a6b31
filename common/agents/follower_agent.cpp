#include "agents/follower_agent.hpp"

#include "agents/controller_agent.hpp"

#include <numbers>

namespace syndds::agents {
namespace {

// The GPS antenna's place along the vehicle (the follower's positions are the antenna's).
double antenna_x(const scenario::VehicleConfig& v) {
  if (!v.sensors || v.sensors->rig.gps.empty()) return 0.0;
  return v.sensors->rig.gps.front().mount.pose.position.x();
}

}  // namespace

convoy::FollowerVehicle follower_vehicle(const scenario::VehicleConfig& own,
                                         const scenario::VehicleConfig* leader,
                                         const scenario::VehicleConfig* trail_source) {
  const vehicle::VehicleParams& p = own.params;
  convoy::FollowerVehicle v;
  v.wheelbase_m = p.wheelbase_m();
  v.half_track_m = p.front.half_track_m;
  v.max_steer_rad = p.steering.max_angle_deg * std::numbers::pi / 180.0;
  v.inner_wheel_input = own.dynamics == "full";
  v.wheel_radius_m = p.wheels.radius_m;
  v.front_m = p.chassis.box_centre_m.x() + p.chassis.half_extents_m.x() - antenna_x(own);
  for (const auto& r : own.sensors ? own.sensors->rig.radars : std::vector<sensors::RadarConfig>{}) {
    if (r.id != own.controller.convoy.radar_sensor) continue;
    v.radar_ahead_of_front_m = r.mount.pose.position.x() - p.chassis.box_centre_m.x() -
                               p.chassis.half_extents_m.x();
  }
  if (leader) {
    const auto& c = leader->params.chassis;
    v.leader_rear_m = c.half_extents_m.x() - c.box_centre_m.x() + antenna_x(*leader);
    v.leader_wheelbase_m = leader->params.wheelbase_m();
  }
  if (trail_source) v.trail_wheelbase_m = trail_source->params.wheelbase_m();
  return v;
}

sensors::GeodeticConverter follower_converter(const scenario::VehicleConfig& v) {
  const auto& rig = v.sensors->rig;
  return sensors::GeodeticConverter(rig.geodetic_origin, rig.gps.front().model);
}

FollowerAgent::FollowerAgent(const scenario::Scenario& scenario,
                             const scenario::VehicleConfig& vehicle)
    : vehicle_id_(vehicle.id),
      leader_id_(vehicle.controller.convoy.leader),
      trail_of_(vehicle.controller.convoy.trail_of == leader_id_ ? ""
                                                                 : vehicle.controller.convoy.trail_of),
      member_id_(scenario::controller_member(vehicle.id)),
      follower_(vehicle.controller.convoy,
                follower_vehicle(vehicle, scenario.find_vehicle(vehicle.controller.convoy.leader),
                                 scenario.find_vehicle(vehicle.controller.convoy.trail_of)),
                follower_converter(vehicle)),
      radar_(!vehicle.controller.convoy.radar_sensor.empty()) {}

std::vector<proto::Subscription> FollowerAgent::subscriptions() const {
  std::vector<proto::Subscription> subs = {{proto::Topic::gps_fix, vehicle_id_},
                                           {proto::Topic::magnetometer, vehicle_id_},
                                           {proto::Topic::wheel_speeds, vehicle_id_},
                                           {proto::Topic::v2v_message, leader_id_}};
  if (!trail_of_.empty()) subs.push_back({proto::Topic::v2v_message, trail_of_});
  if (radar_) subs.push_back({proto::Topic::radar, vehicle_id_});
  return subs;
}

void FollowerAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                         proto::FrameSamples& outputs) {
  if (ctx.frame == 0) return;  // nothing measured yet; the vehicle holds its initial inputs
  convoy::OwnReadings own{inputs.gps_fixes, inputs.magnetometers, inputs.wheel_speeds};
  std::vector<convoy::FollowerEvent> events;
  // The inputs describe the end of frame k-1: that is the time the follower estimates for.
  const double now = ctx.sim_time_s - ctx.heartbeat_s;
  if (radar_) follower_.observe_radar(inputs.radar_scans);
  const auto cmd = follower_.update(now, ctx.heartbeat_s, own, inputs.v2v_messages, events);
  outputs.driver_commands.push_back(command_message(vehicle_id_, member_id_, ctx.frame, cmd));
  for (const auto& e : events) {
    outputs.vehicle_events.push_back(
        {vehicle_id_, member_id_, ctx.frame, ctx.sim_time_s, e.kind, e.detail});
  }
}

void FollowerAgent::save_state(core::StateWriter& w) { follower_.save_state(w); }

void FollowerAgent::load_state(core::StateReader& r) { follower_.load_state(r); }

}  // namespace syndds::agents
