#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>

#include "agents/agent_factory.hpp"
#include "scenario/scenario.hpp"

using namespace syndds;
using namespace syndds::scenario;

namespace {

namespace fs = std::filesystem;

const std::string kConfigDir = SYNDDS_TEST_CONFIG_DIR;

Scenario parse(const std::string& text, const Overrides& o = {}) {
  return parse_scenario(YamlNode::load_string(text, "test.yaml"), text, o, kConfigDir);
}

std::string error_of(const std::string& text) {
  try {
    parse(text);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

const std::string kMinimal = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
vehicles:
  - id: a
    model: hmmwv
    controller:
      type: path_follower
      path: {waypoints: [[0, 0], [10, 0]]}
      speed: {target_mps: 3}
)";

}  // namespace

TEST(Scenario, DefaultScenarioLoads) {
  const auto s = load_scenario(kConfigDir + "/scenarios/default.yaml");
  EXPECT_EQ(s.name, "default");
  EXPECT_GE(s.vehicles.size(), 3u);
  EXPECT_EQ(s.time.steps_per_frame(), 5);
  EXPECT_EQ(s.time.final_frame(), 3000);
  const auto members = s.member_ids();
  EXPECT_EQ(members.front(), "vehicle/lead");
  EXPECT_EQ(members.back(), "recorder");
}

// controller.stop_at_s (path_follower): the emergency stop of docs/convoy.md; a bad value is
// an error naming the file, the line and the key.
TEST(Scenario, PathFollowerStopAtIsATimeAndOnlyForPathFollowers) {
  EXPECT_FALSE(parse(kMinimal).vehicles[0].controller.stop_at_s.has_value());
  const auto with = [](const std::string& value) {
    std::string text = kMinimal;
    text += "      stop_at_s: " + value + "\n";
    return text;
  };
  const auto s = parse(with("12.5"));
  ASSERT_TRUE(s.vehicles[0].controller.stop_at_s.has_value());
  EXPECT_EQ(*s.vehicles[0].controller.stop_at_s, 12.5);
  for (const std::string bad : {"-1", "2e6", ".nan", ".inf"}) {
    SCOPED_TRACE(bad);
    const std::string e = error_of(with(bad));
    EXPECT_NE(e.find("test.yaml:9:18: vehicles[0].controller.stop_at_s: "), std::string::npos) << e;
    const bool finite = bad[0] != '.';
    EXPECT_NE(e.find(finite ? "must be in [0, 1e+06]" : "expected a finite number"),
              std::string::npos)
        << e;
  }
  EXPECT_NE(error_of(with("soon")).find("stop_at_s"), std::string::npos) << error_of(with("soon"));
  // Not a key of the other controllers.
  const std::string none = "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}\n"
                           "vehicles:\n  - id: a\n    model: hmmwv\n"
                           "    controller: {type: none, stop_at_s: 3}\n";
  EXPECT_NE(error_of(none).find("unknown key 'stop_at_s'"), std::string::npos) << error_of(none);
}

TEST(Scenario, MinimalScenarioDefaultsAndMembers) {
  const auto s = parse(kMinimal);
  ASSERT_EQ(s.vehicles.size(), 1u);
  EXPECT_EQ(s.vehicles[0].dynamics, "reduced");
  EXPECT_DOUBLE_EQ(s.vehicles[0].params.wheelbase_m(), 3.378);
  EXPECT_EQ(s.member_ids(), (std::vector<std::string>{"vehicle/a", "controller/a", "recorder"}));
  EXPECT_EQ(s.coordinator.on_member_loss, proto::LossPolicy::abort);
}

TEST(Scenario, OverridesApplyAndChangeTheFingerprint) {
  const auto a = parse(kMinimal);
  Overrides o;
  o.duration_s = 2.5;
  o.realtime = true;
  const auto b = parse(kMinimal, o);
  EXPECT_DOUBLE_EQ(b.time.end_time_s, 2.5);
  EXPECT_TRUE(b.time.realtime);
  EXPECT_EQ(b.time.final_frame(), 250);
  EXPECT_NE(a.fingerprint, b.fingerprint);
  EXPECT_EQ(a.fingerprint, parse(kMinimal).fingerprint);
}

// terrain.colour: the ground's colour in the cameras, for rigid (and height-map) ground; a
// component outside [0, 1] is an error naming the key; the soil's block does not take it.
TEST(Scenario, TerrainColourIsForRigidGround) {
  EXPECT_FALSE(parse(kMinimal).terrain.colour.has_value());
  const auto s = parse(kMinimal + "terrain: {type: rigid, colour: [0.4, 0.3, 0.2]}\n");
  ASSERT_TRUE(s.terrain.colour.has_value());
  EXPECT_EQ(*s.terrain.colour, (std::array<double, 3>{0.4, 0.3, 0.2}));
  EXPECT_NE(s.fingerprint, parse(kMinimal + "terrain: {type: rigid}\n").fingerprint);
  std::string err = error_of(kMinimal + "terrain: {type: rigid, colour: [0.4, 1.3, 0.2]}\n");
  EXPECT_NE(err.find("test.yaml:9:"), std::string::npos) << err;
  EXPECT_NE(err.find("terrain.colour: colour components must be in [0, 1]"), std::string::npos)
      << err;
  err = error_of(kMinimal + "terrain: {type: rigid, colour: [0.4, 0.3]}\n");
  EXPECT_NE(err.find("terrain.colour"), std::string::npos) << err;
  err = error_of(kMinimal +
                 "terrain: {type: scm, preset: soft, spacing_m: 0.1, colour: [0.4, 0.3, 0.2],\n"
                 "          area: {x_min_m: -5, x_max_m: 5, y_min_m: -5, y_max_m: 5}}\n");
  EXPECT_NE(err.find("unknown key 'colour'"), std::string::npos) << err;
}

TEST(Scenario, UnknownKeyIsAnErrorWithLine) {
  std::string text = kMinimal + "colour: red\n";
  const auto err = error_of(text);
  EXPECT_NE(err.find("test.yaml:9:1: colour: unknown key 'colour'"), std::string::npos) << err;
}

TEST(Scenario, NegativeStepIsAnError) {
  std::string text = kMinimal;
  text.replace(text.find("step_s: 0.002"), 13, "step_s: -0.002");
  const auto err = error_of(text);
  EXPECT_NE(err.find("test.yaml:1:"), std::string::npos) << err;
  EXPECT_NE(err.find("time.step_s: must be positive"), std::string::npos) << err;
}

TEST(Scenario, HeartbeatMustBeAWholeMultipleOfTheStep) {
  std::string text = kMinimal;
  text.replace(text.find("heartbeat_s: 0.01"), 17, "heartbeat_s: 0.005");
  text.replace(text.find("step_s: 0.002"), 13, "step_s: 0.003");
  const auto err = error_of(text);
  EXPECT_NE(err.find("time.heartbeat_s: heartbeat_s (0.005) must be a whole multiple of step_s"),
            std::string::npos)
      << err;
}

TEST(Scenario, BadValuesNameTheirKey) {
  std::string text = kMinimal;
  text.replace(text.find("target_mps: 3"), 13, "target_mps: fast");
  auto err = error_of(text);
  EXPECT_NE(err.find("test.yaml:8:27: vehicles[0].controller.speed.target_mps: expected a number"),
            std::string::npos)
      << err;
  text = kMinimal;
  text.replace(text.find("model: hmmwv"), 12, "model: tank");
  err = error_of(text);
  EXPECT_NE(err.find("vehicles[0].model: vehicle model file not found"), std::string::npos) << err;
}

TEST(Scenario, DuplicateVehicleIdsAreRejected) {
  std::string text = kMinimal + R"(  - id: a
    model: hmmwv
    start: {x: 0, y: 5}
)";
  const auto err = error_of(text);
  EXPECT_NE(err.find("duplicate vehicle id 'a'"), std::string::npos) << err;
}

TEST(Scenario, StartDefaultsToThePathStart) {
  std::string text = kMinimal;
  text.replace(text.find("[[0, 0], [10, 0]]"), 17, "[[5, 5], [5, 15]]");
  const auto s = parse(text);
  EXPECT_NEAR(s.vehicles[0].start.position.x(), 5.0, 1e-9);
  EXPECT_NEAR(s.vehicles[0].start.position.y(), 5.0, 1e-9);
  EXPECT_NEAR(yaw_of(s.vehicles[0].start.orientation), std::numbers::pi / 2, 1e-6);
}

TEST(Scenario, VehicleFileErrorsNameTheVehicleFile) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/bad_vehicle.yaml") << "name: x\nchassis: {mass_kg: -5}\n";
  std::string text = kMinimal;
  text.replace(text.find("model: hmmwv"), 12, "model: " + dir + "/bad_vehicle.yaml");
  const auto err = error_of(text);
  EXPECT_NE(err.find("bad_vehicle.yaml:2:"), std::string::npos) << err;
  EXPECT_NE(err.find("chassis.mass_kg: must be positive"), std::string::npos) << err;
}

TEST(Scenario, ObstaclesRestOnTheGroundAndAreChecked) {
  std::string text = kMinimal + R"(terrain: {type: rigid, height_m: 2.0}
obstacles:
  - {id: r1, label: rock, shape: sphere, position: [5, 1], radius_m: 0.5}
  - {id: w1, shape: box, position: [9, 0, 7], size_m: [1, 2, 3], yaw_deg: 90}
  - {id: t1, shape: cylinder, position: [3, 3], radius_m: 0.2, height_m: 4}
)";
  const auto s = parse(text);
  ASSERT_EQ(s.obstacles.size(), 3u);
  EXPECT_DOUBLE_EQ(s.obstacles[0].pose.position.z(), 2.5);  // on the ground
  EXPECT_DOUBLE_EQ(s.obstacles[1].pose.position.z(), 7.0);  // as given
  EXPECT_EQ(s.obstacles[1].size, Vec3(0.5, 1.0, 1.5));      // half extents
  EXPECT_DOUBLE_EQ(s.obstacles[2].pose.position.z(), 4.0);
  EXPECT_EQ(s.obstacles[2].shape, world::ShapeKind::cylinder);

  std::string bad = kMinimal + "obstacles:\n  - {id: r1, shape: cone, position: [5, 1]}\n";
  EXPECT_NE(error_of(bad).find("obstacles[0].shape: must be one of [box, sphere, cylinder]"),
            std::string::npos)
      << error_of(bad);
  bad = kMinimal + "obstacles:\n  - {id: r1, shape: sphere, position: [5], radius_m: 1}\n";
  EXPECT_NE(error_of(bad).find("expected [x, y] or [x, y, z]"), std::string::npos);
}

TEST(Scenario, FullDynamicsIsAccepted) {
  std::string text = kMinimal;
  text.replace(text.find("model: hmmwv"), 12, "model: hmmwv\n    dynamics: full");
  EXPECT_EQ(parse(text).vehicles[0].dynamics, "full");
  text.replace(text.find("dynamics: full"), 14, "dynamics: magic");
  EXPECT_NE(error_of(text).find("vehicles[0].dynamics: must be one of [reduced, full]"),
            std::string::npos);
}

// Every scenario shipped in config/scenarios loads (vehicle files, rigs, height maps, presets).
TEST(Scenario, EveryShippedScenarioLoads) {
  std::size_t n = 0;
  for (const auto& entry :
       std::filesystem::recursive_directory_iterator(kConfigDir + "/scenarios")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const auto s = load_scenario(entry.path().string());
    EXPECT_FALSE(s.vehicles.empty());
    EXPECT_FALSE(s.member_ids().empty());
    ++n;
  }
  EXPECT_GE(n, 13u);  // default, scm_crossing, hills, chase_video, the nine convoys
}

// Convoys: a follower follows another vehicle that broadcasts V2V, and both sides need their
// own GPS, compass and tachometer; every mistake is named with the file and line.
TEST(Scenario, ConvoyMistakesAreNamed) {
  const std::string leader = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
vehicles:
  - id: l1
    model: hmmwv
    sensors: convoy
    v2v: {rate_hz: 10, latency_s: 0.1, drop_probability: 0.2}
    controller:
      type: path_follower
      path: {waypoints: [[0, 0], [10, 0]]}
      speed: {profile: ramp, target_mps: 3}
)";
  const std::string follower = R"(  - id: f1
    model: hmmwv
    start: {x: -12, y: 0}
    sensors: convoy
    controller: {type: follower, follow: l1, gap: {time_s: 1.5, standstill_bumper_m: 3}}
)";
  const auto s = parse(leader + follower);
  ASSERT_EQ(s.vehicles.size(), 2u);
  EXPECT_EQ(s.vehicles[0].controller.follower.speed_profile.accel_mps2, 0.47);  // the paper's
  ASSERT_TRUE(s.vehicles[0].v2v.has_value());
  EXPECT_EQ(s.vehicles[0].v2v->latency_s, 0.1);
  EXPECT_EQ(s.vehicles[1].controller.type, "follower");
  EXPECT_EQ(s.vehicles[1].controller.convoy.leader, "l1");
  EXPECT_EQ(s.vehicles[1].controller.convoy.time_gap_s, 1.5);
  EXPECT_EQ(s.vehicles[1].controller.convoy.standstill_bumper_m, 3.0);
  const auto members = s.member_ids();
  EXPECT_NE(std::find(members.begin(), members.end(), "controller/f1"), members.end());

  auto replaced = [](std::string text, const std::string& from, const std::string& to) {
    text.replace(text.find(from), from.size(), to);
    return text;
  };
  EXPECT_NE(error_of(leader + replaced(follower, "follow: l1", "follow: l9"))
                .find("test.yaml:11:5: vehicles[1]: controller.follow: 'l9' is not another vehicle"),
            std::string::npos)
      << error_of(leader + replaced(follower, "follow: l1", "follow: l9"));
  EXPECT_NE(error_of(leader + replaced(follower, "follow: l1", "follow: f1")).find("is not another"),
            std::string::npos);
  EXPECT_NE(error_of(replaced(leader, "    v2v: {rate_hz: 10, latency_s: 0.1, drop_probability: 0.2}\n", "") +
                     follower)
                .find("vehicle 'l1' sends no V2V messages"),
            std::string::npos);
  EXPECT_NE(error_of(leader + replaced(follower, "    sensors: convoy\n", ""))
                .find("controller: a follower controller needs the vehicle's own GPS, magnetometer"),
            std::string::npos)
      << error_of(leader + replaced(follower, "    sensors: convoy\n", ""));
  EXPECT_NE(error_of(replaced(leader, "    sensors: convoy\n", "")).find("v2v: v2v needs"),
            std::string::npos)
      << error_of(replaced(leader, "    sensors: convoy\n", ""));
  EXPECT_NE(error_of(replaced(leader, "drop_probability: 0.2", "drop_probability: 2"))
                .find("v2v.drop_probability"),
            std::string::npos)
      << error_of(replaced(leader, "drop_probability: 0.2", "drop_probability: 2"));
  EXPECT_NE(error_of(leader + replaced(follower, "gap: {", "gap: {spacing_m: 3, "))
                .find("unknown key"),
            std::string::npos)
      << error_of(leader + replaced(follower, "gap: {", "gap: {spacing_m: 3, "));
  // Two followers following each other: no convoy leader to measure against.
  const std::string circle = replaced(leader, "    controller:\n      type: path_follower\n      path: {waypoints: [[0, 0], [10, 0]]}\n      speed: {profile: ramp, target_mps: 3}\n",
                                      "    start: {x: 0, y: 0}\n    controller: {type: follower, follow: f1}\n") +
                             replaced(follower, "    sensors: convoy\n", "    sensors: convoy\n    v2v: {rate_hz: 10}\n");
  EXPECT_NE(error_of(circle).find("vehicles[0]: controller.follow: follow chain without a leader: l1 -> f1 -> l1"),
            std::string::npos)
      << error_of(circle);
  // The radar gap: a radar of the follower's own rig, named.
  const std::string radar_gap = replaced(
      replaced(follower, "sensors: convoy\n", "sensors: convoy_radar\n"),
      "standstill_bumper_m: 3}}", "standstill_bumper_m: 3}, radar: {sensor: front_radar}}");
  EXPECT_EQ(parse(leader + radar_gap).vehicles[1].controller.convoy.radar_sensor, "front_radar");
  EXPECT_NE(error_of(leader + replaced(radar_gap, "sensor: front_radar", "sensor: rear_radar"))
                .find("controller.radar: no radar 'rear_radar' in the vehicle's sensor rig"),
            std::string::npos)
      << error_of(leader + replaced(radar_gap, "sensor: front_radar", "sensor: rear_radar"));
  EXPECT_NE(error_of(leader + replaced(radar_gap, "sensor: front_radar", "sensor: front_radar, gate: 2"))
                .find("unknown key"),
            std::string::npos);
  // A learned follower: its policy file must exist, its period fit the heartbeat.
  const std::string policy = replaced(
      follower, "controller: {type: follower, follow: l1, gap: {time_s: 1.5, standstill_bumper_m: 3}}",
      "controller: {type: policy, follow: l1, model: no_such_policy.pt}");
  EXPECT_NE(error_of(leader + policy).find("controller.model: policy file not found: no_such_policy.pt"),
            std::string::npos)
      << error_of(leader + policy);
  const std::string odd_period = replaced(policy, "model: no_such_policy.pt",
                                          "model: vehicles/hmmwv.yaml, period_s: 0.015");
  EXPECT_NE(error_of(leader + odd_period)
                .find("period_s (0.015 s) must be a whole multiple of time.heartbeat_s (0.01 s)"),
            std::string::npos)
      << error_of(leader + odd_period);
  // A policy whose sidecar names a perception network: that file is read too (in the
  // fingerprint), and its absence is named.
  const fs::path dir = fs::path(testing::TempDir()) / "policy_with_perception";
  fs::create_directories(dir);
  std::ofstream(dir / "p.pt") << "policy bytes";
  std::ofstream(dir / "p.json") << "{\"env\": \"convoy_follow\", \"perception\": \"perc.pt\"}\n";
  fs::remove(dir / "perc.pt");
  const std::string perceiving = replaced(policy, "model: no_such_policy.pt",
                                          "model: " + (dir / "p.pt").string());
  EXPECT_NE(error_of(leader + perceiving).find("names perception network"), std::string::npos)
      << error_of(leader + perceiving);
  std::ofstream(dir / "perc.pt") << "network one";
  const Scenario one = parse(leader + perceiving);
  const auto perception_file = std::find_if(one.files.begin(), one.files.end(), [](const auto& f) {
    return f.role == "vehicles[1].controller.model (perception)";
  });
  ASSERT_NE(perception_file, one.files.end());
  EXPECT_EQ(fs::path(perception_file->path), dir / "perc.pt");
  std::ofstream(dir / "perc.pt") << "network two";
  EXPECT_NE(parse(leader + perceiving).fingerprint, one.fingerprint);
}

// Each camera, lidar or radar publishes at most one sample a frame; more of one kind on one
// vehicle than its topic's writer keeps per frame is refused when the scenario loads.
TEST(Scenario, TooManyRadarsOnOneVehicleAreRefused) {
  const std::string dir = testing::TempDir();
  auto rig = [&](int radars) {
    const std::string file = dir + "/radars_" + std::to_string(radars) + ".yaml";
    std::ofstream out(file);
    out << "name: radars\nsensors:\n";
    for (int k = 0; k < radars; ++k) out << "  - {id: r" << k << ", type: radar, rate_hz: 20}\n";
    std::string text = kMinimal;
    text.replace(text.find("model: hmmwv"), 12, "model: hmmwv\n    sensors: " + file);
    return text;
  };
  EXPECT_EQ(parse(rig(4)).vehicles[0].sensors->rig.radars.size(), 4u);
  EXPECT_NE(error_of(rig(5)).find("its radar sensors make 5 samples per frame; at most 4 fit"),
            std::string::npos)
      << error_of(rig(5));
}

// The vehicle process simulates the rig's interoceptive sensors only: it builds no camera or
// lidar renderer (each starts its threads and allocates per pixel or ray), the sensor process
// does. Counted by the threads a 16-thread camera would start.
TEST(Scenario, VehicleProcessBuildsNoRenderer) {
  const std::string dir = testing::TempDir();
  std::ofstream(dir + "/render_rig.yaml")
      << "name: render_rig\nsensors:\n"
         "  - {id: gps, type: gps}\n"
         "  - {id: cam, type: camera, width_px: 1920, height_px: 1080, threads: 16}\n";
  std::string text = kMinimal;
  text.replace(text.find("model: hmmwv"), 12,
               "model: hmmwv\n    sensors: " + dir + "/render_rig.yaml");
  const auto s = parse(text);
  auto threads = [] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/task")) ++n;
    return n;
  };
  const std::size_t before = threads();
  const auto vehicle = agents::make_agent(s, vehicle_member("a"), {});
  EXPECT_EQ(threads(), before);
  const auto sensor = agents::make_agent(s, sensor_member("a"), {});
  EXPECT_GE(threads(), before + 15);  // the sensor process renders
}

// `processes:` places the members in processes; the members themselves never change.
TEST(Scenario, ProcessLayoutsGroupEachVehicleWithItsMembers) {
  const std::string text = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
vehicles:
  - {id: a, model: hmmwv, sensors: default,
     controller: {type: path_follower, path: {waypoints: [[0, 0], [10, 0]]}, speed: {target_mps: 3}}}
  - {id: b, model: hmmwv, start: {x: 0, y: 5}, controller: {type: external}}
  - {id: c, model: hmmwv, sensors: {rig: default, late_join: true},
     controller: {type: path_follower, path: {waypoints: [[0, 9], [10, 9]]}, speed: {target_mps: 3}}}
)";
  using Groups = std::vector<std::vector<std::string>>;
  const auto s = parse(text);
  EXPECT_EQ(s.processes.kind, ProcessLayout::Kind::per_member);  // default
  // One process per member; the external controller is the user's own program.
  EXPECT_EQ(s.process_members(s.processes),
            (Groups{{"vehicle/a"}, {"vehicle/b"}, {"vehicle/c"}, {"controller/a"},
                    {"controller/c"}, {"sensor/a"}, {"sensor/c"}, {"recorder"}}));
  // A late-joining sensor keeps its own process (it may be started later).
  EXPECT_EQ(s.process_members(*ProcessLayout::parse("per_vehicle")),
            (Groups{{"vehicle/a", "controller/a", "sensor/a"}, {"vehicle/b"},
                    {"vehicle/c", "controller/c"}, {"sensor/c"}, {"recorder"}}));
  // N processes: consecutive vehicles, sizes differing by at most one; N above the number of
  // vehicles gives one process per vehicle.
  EXPECT_EQ(s.process_members(*ProcessLayout::parse("2")),
            (Groups{{"vehicle/a", "controller/a", "sensor/a", "vehicle/b"},
                    {"vehicle/c", "controller/c"}, {"sensor/c"}, {"recorder"}}));
  EXPECT_EQ(s.process_members(*ProcessLayout::parse("7")),
            s.process_members(*ProcessLayout::parse("per_vehicle")));
  // Every member the coordinator waits for is hosted exactly once, whatever the layout.
  for (const std::string l : {"per_member", "per_vehicle", "1", "2", "3"}) {
    std::vector<std::string> hosted;
    for (const auto& g : s.process_members(*ProcessLayout::parse(l))) {
      hosted.insert(hosted.end(), g.begin(), g.end());
    }
    std::sort(hosted.begin(), hosted.end());
    auto expected = s.member_ids();
    expected.erase(std::remove(expected.begin(), expected.end(), "external/b"), expected.end());
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(hosted, expected) << l;
  }
}

TEST(Scenario, ProcessLayoutErrorsNameTheKey) {
  for (const std::string bad : {"per_host", "0", "-2", "1.5", "1000"}) {
    EXPECT_FALSE(ProcessLayout::parse(bad).has_value()) << bad;
  }
  EXPECT_EQ(ProcessLayout::parse("12")->groups, 12);
  const auto err = error_of("processes: per_host\n" + kMinimal);
  EXPECT_NE(err.find("test.yaml:1:12: processes: 'per_host': expected per_member, per_vehicle or "
                     "a number of processes"),
            std::string::npos)
      << err;
}

// Soil routing needs interest management and the recorder (which keeps the whole soil); each
// refusal names the key and its line.
TEST(Scenario, SoilRoutingNeedsInterestManagementAndTheRecorder) {
  const std::string soil =
      "terrain: {type: scm, preset: soft, spacing_m: 0.05, routing: true,\n"
      "          area: {x_min_m: -5, x_max_m: 20, y_min_m: -5, y_max_m: 5}";
  EXPECT_TRUE(parse(soil + "}\n" + kMinimal).terrain.scm.routing);
  auto err = error_of(soil + ", interest_radius_m: 0}\n" + kMinimal);
  EXPECT_NE(err.find("test.yaml:1:"), std::string::npos) << err;
  EXPECT_NE(err.find("routing needs interest management (interest_radius_m > 0)"),
            std::string::npos)
      << err;
  err = error_of(soil + "}\nrecorder: {enabled: false}\n" + kMinimal);
  EXPECT_NE(err.find("test.yaml:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("cannot be disabled with routing"), std::string::npos) << err;
}

TEST(Scenario, CheckpointsComeEveryWholeNumberOfFrames) {
  const auto s = parse(kMinimal + "checkpoint: {every_s: 0.5}\n");
  EXPECT_TRUE(s.checkpoint.enabled());
  EXPECT_EQ(s.checkpoint.every_frames, 50);
  EXPECT_FALSE(parse(kMinimal).checkpoint.enabled());
  auto err = error_of(kMinimal + "checkpoint: {every_s: 0.015}\n");
  EXPECT_NE(err.find("test.yaml:9:"), std::string::npos) << err;
  EXPECT_NE(err.find("every_s (0.015) must be a whole multiple of heartbeat_s (0.01)"),
            std::string::npos)
      << err;
  err = error_of(kMinimal + "checkpoint: {}\n");
  EXPECT_NE(err.find("every_s"), std::string::npos) << err;
  err = error_of(kMinimal + "checkpoint: {every_s: 1, each: 2}\n");
  EXPECT_NE(err.find("unknown key 'each'"), std::string::npos) << err;
}

// keep_last: how many complete checkpoints the run directory keeps (3 unless said; at least 1,
// the one a resume or a recovery starts from).
TEST(Scenario, CheckpointsKeptAreAWholeNumberOfAtLeastOne) {
  EXPECT_EQ(parse(kMinimal + "checkpoint: {every_s: 0.5}\n").checkpoint.keep_last, 3);
  EXPECT_EQ(parse(kMinimal + "checkpoint: {every_s: 0.5, keep_last: 1}\n").checkpoint.keep_last, 1);
  EXPECT_EQ(
      parse(kMinimal + "checkpoint:\n  every_s: 0.5\n  keep_last: 1000000\n").checkpoint.keep_last,
      1000000);
  auto err = error_of(kMinimal + "checkpoint:\n  every_s: 0.5\n  keep_last: 0\n");
  EXPECT_NE(err.find("test.yaml:11:14: checkpoint.keep_last: must be at least 1"),
            std::string::npos)
      << err;
  err = error_of(kMinimal + "checkpoint: {every_s: 0.5, keep_last: 2.5}\n");
  EXPECT_NE(err.find("checkpoint.keep_last: expected an integer, got '2.5'"), std::string::npos)
      << err;
  err = error_of(kMinimal + "checkpoint: {every_s: 0.5, keep_last: all}\n");
  EXPECT_NE(err.find("checkpoint.keep_last: expected an integer, got 'all'"), std::string::npos)
      << err;
  err = error_of(kMinimal + "checkpoint: {every_s: 0.5, keep: 2}\n");
  EXPECT_NE(err.find("unknown key 'keep'"), std::string::npos) << err;
}

// External controllers cannot checkpoint yet: a scenario that asks is refused naming the
// member, before anything runs.
TEST(Scenario, AMemberThatCannotCheckpointIsNamed) {
  const auto s = parse(kMinimal + "checkpoint: {every_s: 0.5}\n");
  struct NoState : proto::Agent {
    std::string id = "controller/x";
    const std::string& member_id() const override { return id; }
    proto::MemberKind kind() const override { return proto::MemberKind::controller; }
    std::vector<proto::Subscription> subscriptions() const override { return {}; }
    std::vector<proto::Topic> publications() const override { return {}; }
    void step(const proto::FrameContext&, const proto::FrameSamples&,
              proto::FrameSamples&) override {}
  } agent;
  try {
    agents::require_checkpoints(s, agent);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("member controller/x cannot write checkpoints"),
              std::string::npos)
        << e.what();
  }
}

// The height map is decoded from the same single read whose bytes are checked against the
// fingerprint: an image changed between loading the scenario and building the terrain is an
// error naming the file, never another terrain.
TEST(Scenario, HeightMapChangedAfterLoadingIsRefusedWhenTheTerrainIsBuilt) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(testing::TempDir()) / ("syndds_hills_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::copy_file(kConfigDir + "/heightmaps/rolling_hills.png", dir / "hills.png");
  const std::string file = (dir / "s.yaml").string();
  std::ofstream(file) << R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
terrain:
  type: heightmap
  heightmap: {image: hills.png, size_m: [200, 200], height_range_m: [0, 6]}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0}
)";
  const auto s = load_scenario_config(file, {}, kConfigDir);
  EXPECT_NE(s.terrain.heightmap.image_hash, 0u);
  EXPECT_NO_THROW(make_terrain(s.terrain));
  std::ofstream(dir / "hills.png", std::ios::app | std::ios::binary) << '\0';
  try {
    make_terrain(s.terrain);
    ADD_FAILURE() << "a changed height map was used";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("hills.png: height-map image changed after the scenario "
                                         "was loaded"),
              std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

// `trail: head`: a follower steers along the trail of its convoy's head, the end of its follow
// chain (the leader itself for the first follower); leader (the default) keeps its leader's.
TEST(Scenario, AFollowersTrailIsItsLeadersOrItsConvoyHeads) {
  std::string text = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
vehicles:
  - id: l1
    model: hmmwv
    sensors: convoy
    v2v: {rate_hz: 10}
    controller:
      type: path_follower
      path: {waypoints: [[0, 0], [10, 0]]}
      speed: {profile: ramp, target_mps: 3}
)";
  for (const char* f : {"  - {id: f1, model: hmmwv, start: {x: -12, y: 0}, sensors: convoy, v2v: {rate_hz: 10},"
                        " controller: {type: follower, follow: l1, trail: head}}\n",
                        "  - {id: f2, model: hmmwv, start: {x: -24, y: 0}, sensors: convoy, v2v: {rate_hz: 10},"
                        " controller: {type: follower, follow: f1, trail: head}}\n",
                        "  - {id: f3, model: hmmwv, start: {x: -36, y: 0}, sensors: convoy,"
                        " controller: {type: follower, follow: f2, trail: leader}}\n"}) {
    text += f;
  }
  const auto s = parse(text);
  EXPECT_EQ(s.vehicles[1].controller.convoy.trail_of, "l1");
  EXPECT_EQ(s.vehicles[2].controller.convoy.trail_of, "l1");
  EXPECT_EQ(s.vehicles[2].controller.convoy.leader, "f1");
  EXPECT_EQ(s.vehicles[3].controller.convoy.trail_of, "");
  const std::string bad = error_of(text.replace(text.find("trail: leader"), 13, "trail: middle"));
  EXPECT_NE(bad.find("test.yaml:13:"), std::string::npos) << bad;
  EXPECT_NE(bad.find("trail"), std::string::npos) << bad;
  EXPECT_NE(bad.find("head"), std::string::npos) << bad;
}

// recorder.skip names files by their stem; vehicles and events (the summaries' source), names
// that are no file and names given twice are refused with the line.
TEST(Scenario, TheRecorderSkipsTheNamedFilesOnly) {
  const auto s = parse(kMinimal + "recorder: {skip: [commands, wheels, gps]}\n");
  EXPECT_EQ(s.recorder.skip, (std::set<std::string>{"commands", "gps", "wheels"}));
  EXPECT_FALSE(s.recorder.records("commands"));
  EXPECT_TRUE(s.recorder.records("imu"));
  EXPECT_TRUE(parse(kMinimal).recorder.skip.empty());
  for (const std::string bad : {"vehicles", "events", "commands.csv"}) {
    const auto err = error_of(kMinimal + "recorder:\n  skip: [wheels,\n    " + bad + "]\n");
    EXPECT_NE(err.find("test.yaml:11:"), std::string::npos) << err;
    EXPECT_NE(err.find("'" + bad + "' is not a file the recorder may skip (commands, wheels"),
              std::string::npos)
        << err;
  }
  auto err = error_of(kMinimal + "recorder: {skip: [radar, radar]}\n");
  EXPECT_NE(err.find("test.yaml:9:"), std::string::npos) << err;
  EXPECT_NE(err.find("'radar' is listed twice"), std::string::npos) << err;
  err = error_of(kMinimal + "recorder: {skip: commands}\n");
  EXPECT_NE(err.find("expected a list of file names"), std::string::npos) << err;
}
