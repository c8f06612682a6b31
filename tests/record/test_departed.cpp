// Members lost under on_member_loss: continue, as the vehicle and sensor agents see them
// (FrameContext::departed): a vehicle whose controller is gone brakes to a stop, a vehicle that
// is gone leaves the other vehicles' sensor scenes.
#include <gtest/gtest.h>

#include <algorithm>

#include "agents/sensor_agent.hpp"
#include "agents/vehicle_agent.hpp"
#include "record_test_util.hpp"

using namespace syndds;
using namespace syndds::test;

namespace {

proto::FrameContext context(std::int64_t frame, std::vector<std::string> departed = {}) {
  proto::FrameContext ctx;
  ctx.frame = frame;
  ctx.heartbeat_s = 0.01;
  ctx.sim_time_s = static_cast<double>(frame) * ctx.heartbeat_s;
  ctx.departed = std::move(departed);
  return ctx;
}

std::string scenario_text(const std::string& controller) {
  return R"(name: departed
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 100.0}
vehicles:
  - id: a
    model: hmmwv
    dynamics: reduced
    start: {x: 0, y: 0, yaw_deg: 0}
    controller: )" + controller + R"(
  - id: b
    model: hmmwv
    dynamics: reduced
    controller: {type: path_follower, path: {waypoints: [[0, 10], [100, 10]]}, speed: {target_mps: 5}}
)";
}

struct Driven {
  std::vector<proto::VehicleStateMsg> states;
  std::vector<proto::VehicleEventMsg> events;
};

// Drives vehicle a with full throttle and some steering from `controller` for `frames` frames,
// then reports `departed` lost and lets it run on without commands.
Driven drive_then_lose(const scenario::Scenario& s, const std::string& controller,
                       const std::vector<std::string>& departed) {
  agents::VehicleAgent vehicle(s, s.vehicles.front());
  Driven d;
  const std::int64_t lost_at = 300, end = 1300;
  for (std::int64_t k = 0; k < end; ++k) {
    proto::FrameSamples in, out;
    if (k > 0 && k < lost_at) {
      in.driver_commands.push_back({"a", controller, k - 1, 0.2, 1.0, 0.0});
    }
    vehicle.step(context(k, k == lost_at ? departed : std::vector<std::string>{}), in, out);
    d.states.push_back(out.vehicle_states.at(0));
    for (auto& e : out.vehicle_events) d.events.push_back(e);
  }
  return d;
}

}  // namespace

TEST(Departed, AVehicleWhoseControllerIsLostBrakesToAStop) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(
      dir, scenario_text("{type: path_follower, path: {waypoints: [[0, 0], [100, 0]]}, "
                         "speed: {target_mps: 5}}"));
  const Driven d = drive_then_lose(s, "controller/a", {"controller/a"});
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].kind, "controller_lost");
  EXPECT_EQ(d.events[0].frame, 300);
  EXPECT_NE(d.events[0].detail.find("controller/a"), std::string::npos) << d.events[0].detail;
  EXPECT_GT(d.states[299].linear_velocity.norm(), 3.0);  // it was driving
  for (std::size_t k = 300; k < d.states.size(); ++k) {
    EXPECT_EQ(d.states[k].throttle, 0.0) << "frame " << k;
    EXPECT_EQ(d.states[k].braking, 1.0) << "frame " << k;
    EXPECT_EQ(d.states[k].steering, d.states[299].steering) << "frame " << k;
  }
  EXPECT_LT(d.states.back().linear_velocity.norm(), 0.1);
}

TEST(Departed, AVehicleWhoseExternalDriverIsLostBrakesToAStop) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, scenario_text("{type: external}"));
  const Driven d = drive_then_lose(s, "external/a", {"external/a"});
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].kind, "controller_lost");
  EXPECT_EQ(d.states.back().throttle, 0.0);
  EXPECT_EQ(d.states.back().braking, 1.0);
  EXPECT_LT(d.states.back().linear_velocity.norm(), 0.1);
}

TEST(Departed, AnotherVehiclesControllerLostChangesNothing) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(
      dir, scenario_text("{type: path_follower, path: {waypoints: [[0, 0], [100, 0]]}, "
                         "speed: {target_mps: 5}}"));
  const Driven d = drive_then_lose(s, "controller/a", {"controller/b", "vehicle/b"});
  EXPECT_TRUE(d.events.empty());
  EXPECT_EQ(d.states.back().throttle, 1.0);  // its last command still holds
}

TEST(Departed, ALostVehicleLeavesTheSensorScene) {
  const fs::path dir = test_dir();
  const auto s = scenario_from(dir, R"(name: departed_sensor
time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1.0}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0, yaw_deg: 0}
    sensors: {rig: default}
  - id: b
    model: hmmwv
    start: {x: 15, y: 0, yaw_deg: 0}
    controller: {type: path_follower, path: {waypoints: [[15, 0], [40, 0]]}, speed: {target_mps: 4}}
)");
  const auto it = std::find_if(s.vehicles.begin(), s.vehicles.end(),
                               [](const auto& v) { return v.id == "a"; });
  agents::SensorAgent sensor(s, *it, {(dir / "sensors").string()});
  auto state = [](const std::string& id, std::int64_t frame, double x) {
    proto::VehicleStateMsg m;
    m.vehicle_id = id;
    m.source = scenario::vehicle_member(id);
    m.frame = frame;
    m.pose.position = Vec3(x, 0.0, 0.5);
    return m;
  };
  proto::FrameSamples out;
  sensor.step(context(0), {}, out);
  proto::FrameSamples in;
  in.vehicle_states = {state("a", 0, 0.0), state("b", 0, 15.0)};
  sensor.step(context(1), in, out);
  ASSERT_TRUE(sensor.scene().has_vehicle("b"));
  in.vehicle_states = {state("a", 1, 0.0)};  // b's last state was stamped 0
  sensor.step(context(2, {"vehicle/b"}), in, out);
  EXPECT_FALSE(sensor.scene().has_vehicle("b")) << "the lost vehicle stays frozen in the scene";
  EXPECT_TRUE(sensor.scene().has_vehicle("a"));
  // A lost controller is not a lost vehicle.
  sensor.step(context(3, {"controller/a"}), {}, out);
  EXPECT_TRUE(sensor.scene().has_vehicle("a"));
}
