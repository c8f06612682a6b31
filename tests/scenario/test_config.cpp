// The configuration layer alone (this binary links syndds_config and nothing heavy): budgets
// and bounds, so that every input that would make a process allocate or compute in proportion
// to a number in a file is refused at load naming the file, line and key; and the fingerprint
// over every file a process loads.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "protocol/messages.hpp"
#include "scenario/scenario.hpp"

using namespace syndds;
using namespace syndds::scenario;
namespace fs = std::filesystem;

namespace {

const std::string kConfigDir = SYNDDS_TEST_CONFIG_DIR;

Scenario parse(const std::string& text, const Overrides& o = {},
               const std::string& config_dir = kConfigDir) {
  return parse_scenario_config(YamlNode::load_string(text, "test.yaml"), text, o, config_dir);
}

std::string error_of(const std::string& text, const Overrides& o = {}) {
  try {
    parse(text, o);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::logic_error("test text has no '" + from + "'");
  return text.replace(at, from.size(), to);
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

// A scratch copy of the parts of config/ a scenario loads, to change one file at a time.
struct ScratchConfig {
  fs::path dir;
  explicit ScratchConfig(const std::string& name) {
    dir = fs::path(testing::TempDir()) /
          ("syndds_config_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    for (const char* sub : {"vehicles", "sensors", "terrain", "heightmaps", "scenarios"}) {
      fs::create_directories(dir / sub);
    }
    fs::copy_file(kConfigDir + "/vehicles/hmmwv.yaml", dir / "vehicles/hmmwv.yaml");
    fs::copy_file(kConfigDir + "/sensors/convoy.yaml", dir / "sensors/convoy.yaml");
    fs::copy_file(kConfigDir + "/terrain/scm_mid.yaml", dir / "terrain/scm_mid.yaml");
    fs::copy_file(kConfigDir + "/heightmaps/rolling_hills.png", dir / "heightmaps/hills.png");
  }
  ~ScratchConfig() { fs::remove_all(dir); }
  void append(const std::string& file, const std::string& bytes) const {
    std::ofstream(dir / file, std::ios::app | std::ios::binary) << bytes;
  }
  std::uint64_t fingerprint(const std::string& text) const {
    const std::string file = (dir / "scenarios/s.yaml").string();
    std::ofstream(file) << text;
    return load_scenario_config(file, {}, dir.string()).fingerprint;
  }
};

const std::string kScmScenario = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
terrain: {type: scm, preset: mid, spacing_m: 0.1, area: {x_min_m: -5, x_max_m: 15, y_min_m: -5, y_max_m: 5}}
vehicles:
  - id: a
    model: hmmwv
    sensors: convoy
    controller:
      type: path_follower
      path: {waypoints: [[0, 0], [10, 0]]}
      speed: {target_mps: 3}
)";

const std::string kHeightmapScenario = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
terrain:
  type: heightmap
  heightmap: {image: ../heightmaps/hills.png, size_m: [200, 200], height_range_m: [0, 6]}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0}
)";

}  // namespace

// Every file a process reads is part of the fingerprint compared at join: a host with another
// vehicle file, rig, soil preset or height map must not run different physics silently.
TEST(ConfigFingerprint, CoversEveryFileTheScenarioLoads) {
  const ScratchConfig cfg("fingerprint");
  const auto scm0 = cfg.fingerprint(kScmScenario);
  EXPECT_EQ(scm0, cfg.fingerprint(kScmScenario));
  cfg.append("vehicles/hmmwv.yaml", "\n# another host's copy\n");
  const auto scm1 = cfg.fingerprint(kScmScenario);
  EXPECT_NE(scm1, scm0) << "vehicle file";
  cfg.append("sensors/convoy.yaml", "\n# another host's copy\n");
  const auto scm2 = cfg.fingerprint(kScmScenario);
  EXPECT_NE(scm2, scm1) << "sensor rig";
  cfg.append("terrain/scm_mid.yaml", "\n# another host's copy\n");
  EXPECT_NE(cfg.fingerprint(kScmScenario), scm2) << "soil preset";

  const auto hills0 = cfg.fingerprint(kHeightmapScenario);
  cfg.append("heightmaps/hills.png", std::string(1, '\0'));
  EXPECT_NE(cfg.fingerprint(kHeightmapScenario), hills0) << "height-map image";
}

// The meshes a camera draws (its rig's mesh folder: every obstacle label and vehicle_body) are
// in the fingerprint, present or absent, and a mismatch names the mesh file.
TEST(ConfigFingerprint, CoversTheMeshesARendererDraws) {
  const ScratchConfig cfg("meshes");
  fs::copy_file(kConfigDir + "/sensors/default.yaml", cfg.dir / "sensors/default.yaml");
  fs::copy(kConfigDir + "/meshes", cfg.dir / "meshes");
  const std::string text = R"(time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}
obstacles:
  - {id: r1, label: rock, shape: sphere, position: [25, 6], radius_m: 1.5}
  - {id: w1, label: wall, shape: box, position: [5, 9], size_m: [1, 1, 1]}
vehicles:
  - id: a
    model: hmmwv
    start: {x: 0, y: 0}
    sensors: default
)";
  const std::string file = (cfg.dir / "scenarios/s.yaml").string();
  std::ofstream(file) << text;
  const auto before = load_scenario_config(file, {}, cfg.dir.string());
  std::vector<std::string> roles;
  for (const auto& f : before.files) roles.push_back(f.role);
  for (const char* role : {"vehicles[0].sensors.meshes.meshes.mtl",
                           "vehicles[0].sensors.meshes.rock.obj",
                           "vehicles[0].sensors.meshes.vehicle_body.obj",
                           "vehicles[0].sensors.meshes.wall.obj (absent)"}) {
    EXPECT_NE(std::find(roles.begin(), roles.end(), role), roles.end()) << role;
  }
  // The renderer is told the hashes, to check the bytes it draws.
  const auto& hashes = before.find_vehicle("a")->sensors->rig.scene.mesh_hashes;
  EXPECT_NE(hashes.at("rock"), 0u);
  EXPECT_EQ(hashes.at("wall"), 0u);

  cfg.append("meshes/rock.obj", "# another host's rock\n");
  const auto after = load_scenario_config(file, {}, cfg.dir.string());
  EXPECT_NE(after.fingerprint, before.fingerprint);
  const std::string d = proto::config_file_differences(fingerprint_lines(before.files),
                                                       fingerprint_lines(after.files));
  EXPECT_EQ(d.find("vehicles[0].sensors.meshes.rock.obj ("), 0u) << d;
  EXPECT_EQ(d.find(';'), std::string::npos) << d;  // only that one

  fs::remove(cfg.dir / "meshes/rock.obj");
  const auto gone = load_scenario_config(file, {}, cfg.dir.string());
  EXPECT_NE(gone.fingerprint, before.fingerprint);
  EXPECT_NE(gone.fingerprint, after.fingerprint);
  EXPECT_NE(proto::config_file_differences(fingerprint_lines(before.files),
                                           fingerprint_lines(gone.files))
                .find("vehicles[0].sensors.meshes.rock.obj (absent) (only there)"),
            std::string::npos);
}

// time.end_time_s 1e17 made final_frame() negative: a run that "completed" after frame 0.
TEST(ConfigBounds, DurationIsBounded) {
  auto err = error_of(replaced(kMinimal, "end_time_s: 1}", "end_time_s: 1e17}"));
  EXPECT_NE(err.find("test.yaml:1:"), std::string::npos) << err;
  EXPECT_NE(err.find("time.end_time_s: must be in"), std::string::npos) << err;
  Overrides o;
  o.duration_s = 1e17;
  err = error_of(kMinimal, o);
  EXPECT_NE(err.find("--duration"), std::string::npos) << err;
  EXPECT_NE(err.find("1e+06"), std::string::npos) << err;  // names the maximum
  // The largest accepted duration still has a positive final frame.
  o.duration_s = 1e6;
  EXPECT_EQ(parse(kMinimal, o).time.final_frame(), 100000000);
  // A step so short that a frame holds billions of steps is refused as well.
  err = error_of(replaced(kMinimal, "step_s: 0.002, heartbeat_s: 0.01",
                          "step_s: 1e-12, heartbeat_s: 10"));
  EXPECT_NE(err.find("time."), std::string::npos) << err;
}

// Coordinates far away made the sensor process allocate gigabytes (rendered ground) and a
// start at (1e6, 1e6) threw bad_alloc: every position must lie in the scenario's world box.
TEST(ConfigBounds, CoordinatesMustLieInTheWorld) {
  auto err = error_of(replaced(kMinimal, "[[0, 0], [10, 0]]", "[[0, 0], [-1e6, 0]]"));
  EXPECT_NE(err.find("test.yaml:7:"), std::string::npos) << err;
  EXPECT_NE(err.find("vehicles[0].controller.path.waypoints[1]"), std::string::npos) << err;
  EXPECT_NE(err.find("outside the world"), std::string::npos) << err;

  const std::string with_start = replaced(kMinimal, "    model: hmmwv\n",
                                          "    model: hmmwv\n    start: {x: 1e6, y: 1e6}\n");
  err = error_of(with_start);
  EXPECT_NE(err.find("vehicles[0].start"), std::string::npos) << err;
  EXPECT_NE(err.find("outside the world"), std::string::npos) << err;

  err = error_of(kMinimal + "obstacles:\n  - {id: r, shape: sphere, position: [3e4, 0], radius_m: 1}\n");
  EXPECT_NE(err.find("obstacles[0].position"), std::string::npos) << err;
  EXPECT_NE(err.find("outside the world"), std::string::npos) << err;
}

// 500 vehicles aborted on the join timeout after 30 s while processes kept starting.
TEST(ConfigBounds, NumberOfVehiclesIsBounded) {
  std::string text = "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}\nvehicles:\n";
  for (int i = 0; i < 50; ++i) {
    text += "  - {id: v" + std::to_string(i) + ", model: hmmwv, start: {x: " +
            std::to_string(i * 10) + ", y: 0}}\n";
  }
  const auto err = error_of(text);
  EXPECT_NE(err.find("test.yaml:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("vehicles: 50 vehicles"), std::string::npos) << err;
  EXPECT_NE(err.find("at most 48"), std::string::npos) << err;
}

// Rigs: budgets on the rays of a lidar and the pixels of a camera (per frame), checked in
// constant time; ids that would break CSV columns and file names are refused.
namespace {

std::string rig_error(const std::string& sensor_yaml) {
  // One folder per test and process: CTest runs the cases of this binary in parallel.
  const fs::path dir =
      fs::path(testing::TempDir()) /
      ("syndds_config_rig_" +
       std::string(testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
       std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "rig.yaml") << "name: test\nsensors:\n" << sensor_yaml;
  std::string text = replaced(kMinimal, "    model: hmmwv\n",
                              "    model: hmmwv\n    sensors: " + (dir / "rig.yaml").string() + "\n");
  const std::string error = error_of(text);
  fs::remove_all(dir);
  return error;
}

}  // namespace

TEST(ConfigBudgets, LidarRaysAreBounded) {
  EXPECT_EQ(rig_error("  - {id: l, type: lidar, channels: 64, samples: 2048}\n"), "");
  auto err = rig_error("  - {id: l, type: lidar, channels: 1024, samples: 65535}\n");
  EXPECT_NE(err.find("rig.yaml:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("sensors[0]"), std::string::npos) << err;
  EXPECT_NE(err.find("rays per scan"), std::string::npos) << err;
  err = rig_error("  - {id: l, type: lidar, channels: 1024, samples: 4096}\n");
  EXPECT_NE(err.find("rays per scan"), std::string::npos) << err;
  err = rig_error("  - {id: l, type: lidar, channels: 128, samples: 4096, beam: {samples: 8}}\n");
  EXPECT_NE(err.find("rays per scan"), std::string::npos) << err;
}

TEST(ConfigBudgets, CameraPixelsAreBounded) {
  EXPECT_EQ(rig_error("  - {id: c, type: camera, width_px: 7680, height_px: 4320}\n"), "");
  const auto err = rig_error(
      "  - {id: c, type: camera, width_px: 7680, height_px: 4320,"
      " exposure: {window_s: 0.01, mode: average, subframes: 4}}\n");
  EXPECT_NE(err.find("sensors[0]"), std::string::npos) << err;
  EXPECT_NE(err.find("pixels per frame"), std::string::npos) << err;
}

TEST(ConfigBudgets, SensorIdsAreSafeForFilesAndCsv) {
  for (const char* bad : {"'a,b'", "'a b'", "'..'", "'a\"b'", "'x;y'"}) {
    const auto err = rig_error(std::string("  - {id: ") + bad + ", type: tachometer}\n");
    EXPECT_NE(err.find("sensors[0].id"), std::string::npos) << bad << ": " << err;
  }
  EXPECT_EQ(rig_error("  - {id: front_cam-2.L, type: tachometer}\n"), "");
}

// Files and roles behind the fingerprint, in load order, so a refused member's host can be
// compared file by file with the coordinator's.
TEST(ConfigFingerprint, ListsEveryFileWithItsRole) {
  const ScratchConfig cfg("files");
  const std::string file = (cfg.dir / "scenarios/s.yaml").string();
  std::ofstream(file) << kScmScenario;
  const auto s = load_scenario_config(file, {}, cfg.dir.string());
  ASSERT_EQ(s.files.size(), 4u);
  EXPECT_EQ(s.files[0].role, "scenario");
  EXPECT_EQ(s.files[1].role, "terrain.preset");
  EXPECT_EQ(s.files[2].role, "vehicles[0].model");
  EXPECT_EQ(s.files[3].role, "vehicles[0].sensors");
  EXPECT_EQ(fs::path(s.files[2].path).filename(), "hmmwv.yaml");
  EXPECT_EQ(s.files[2].size, fs::file_size(cfg.dir / "vehicles/hmmwv.yaml"));
  // Where config/ lives is not part of it: the same bytes elsewhere give the same fingerprint.
  const ScratchConfig moved("files_elsewhere");
  const std::string file2 = (moved.dir / "scenarios/s.yaml").string();
  std::ofstream(file2) << kScmScenario;
  EXPECT_EQ(load_scenario_config(file2, {}, moved.dir.string()).fingerprint, s.fingerprint);
}

// The config layer builds nothing: an obstacle without z keeps it unresolved (the processes
// that simulate place it on the ground, scenario.hpp), and nothing heavy is linked.
TEST(ConfigLayer, BuildsNoTerrainAndLinksNothingHeavy) {
  const auto s = parse(kMinimal + "obstacles:\n  - {id: r, shape: sphere, position: [3, 0], radius_m: 1}\n");
  ASSERT_EQ(s.obstacles.size(), 1u);
  EXPECT_TRUE(std::isnan(s.obstacles[0].pose.position.z()));
  std::ifstream maps("/proc/self/maps");
  const std::string mapped((std::istreambuf_iterator<char>(maps)), std::istreambuf_iterator<char>());
  for (const char* lib : {"libode", "libembree", "libopencv"}) {
    EXPECT_EQ(mapped.find(lib), std::string::npos) << lib << " is loaded by the config layer";
  }
}

// Vehicles with controllers and rendered sensors are three processes each: the members of a
// run are bounded as well as the vehicles.
TEST(ConfigBounds, NumberOfProcessesIsBounded) {
  std::string text = "time: {step_s: 0.002, heartbeat_s: 0.01, end_time_s: 1}\nvehicles:\n";
  for (int i = 0; i < 34; ++i) {
    const std::string y = std::to_string(i * 10);
    text += "  - {id: v" + std::to_string(i) + ", model: hmmwv, sensors: default, controller: " +
            "{type: path_follower, path: {waypoints: [[0, " + y + "], [50, " + y + "]]}, " +
            "speed: {target_mps: 3}}}\n";
  }
  const auto err = error_of(text);
  EXPECT_NE(err.find("test.yaml:3:"), std::string::npos) << err;
  EXPECT_NE(err.find("103 processes"), std::string::npos) << err;
  EXPECT_NE(err.find("at most 100"), std::string::npos) << err;
}

// The world box may be declared elsewhere, never larger than its maximum.
TEST(ConfigBounds, WorldBoxIsDeclaredWithinItsMaximum) {
  const std::string far = replaced(kMinimal, "[[0, 0], [10, 0]]", "[[5000, 0], [5010, 0]]");
  EXPECT_NE(error_of(far).find("outside the world [-1000, 1000] x [-1000, 1000]"),
            std::string::npos)
      << error_of(far);
  const auto s = parse(far + "world: {x_min_m: 4500, x_max_m: 6000, y_min_m: -500, y_max_m: 500}\n");
  EXPECT_EQ(s.world.x_min_m, 4500.0);
  EXPECT_DOUBLE_EQ(s.vehicles[0].start.position.x(), 5000.0);
  const auto err =
      error_of(far + "world: {x_min_m: 3000, x_max_m: 6000, y_min_m: -500, y_max_m: 500}\n");
  EXPECT_NE(err.find("world: the world's x extent [3000, 6000] must be non-empty and at most 2000"),
            std::string::npos)
      << err;
  EXPECT_NE(error_of(kMinimal + "world: {x_min_m: -2e5}\n").find("world.x_min_m: must be in"),
            std::string::npos);
}

// Every process that holds the soil keeps its whole grid: the patch is bounded at load.
TEST(ConfigBudgets, ScmPatchIsBounded) {
  const std::string big = replaced(kMinimal, "vehicles:",
                                   "terrain: {type: scm, preset: mid, spacing_m: 0.05, area: "
                                   "{x_min_m: -500, x_max_m: 500, y_min_m: -500, y_max_m: 500}}\n"
                                   "vehicles:");
  const auto err = error_of(big);
  EXPECT_NE(err.find("test.yaml:2:"), std::string::npos) << err;
  EXPECT_NE(err.find("terrain: the soil patch"), std::string::npos) << err;
  EXPECT_NE(err.find("grid vertices; at most 8.38861e+06"), std::string::npos) << err;
}

// Deadlines are computed on the steady clock: a timeout of 1e300 s wrapped around.
TEST(ConfigBounds, CoordinatorTimeoutsAreBounded) {
  const auto err = error_of(kMinimal + "coordinator: {join_timeout_s: 1e300}\n");
  EXPECT_NE(err.find("test.yaml:9:"), std::string::npos) << err;
  EXPECT_NE(err.find("coordinator.join_timeout_s: must be in [0.001, 86400]"), std::string::npos)
      << err;
  EXPECT_NE(error_of(kMinimal + "coordinator: {frame_timeout_s: 1e9}\n")
                .find("coordinator.frame_timeout_s"),
            std::string::npos);
}

// Every process that builds the terrain decodes the whole height map: its size is read from
// the PNG header at load.
TEST(ConfigBudgets, HeightmapImageIsBounded) {
  const ScratchConfig cfg("heightmap");
  std::string header("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR\0\x01\x86\xa0\0\x01\x86\xa0\x10\0\0\0\0", 33);
  std::ofstream(cfg.dir / "heightmaps/hills.png", std::ios::binary | std::ios::trunc) << header;
  const std::string file = (cfg.dir / "scenarios/s.yaml").string();
  std::ofstream(file) << kHeightmapScenario;
  std::string err;
  try {
    load_scenario_config(file, {}, cfg.dir.string());
  } catch (const ConfigError& e) {
    err = e.what();
  }
  EXPECT_NE(err.find("s.yaml:4:"), std::string::npos) << err;
  EXPECT_NE(err.find("terrain.heightmap.image"), std::string::npos) << err;
  EXPECT_NE(err.find("is 100000 x 100000 pixels; at most"), std::string::npos) << err;
}

// A sensor faster than the grid it is fed at (the frame for cameras) used to pass the load
// and fail only when its process built it, after the others had started.
TEST(ConfigBudgets, SensorRatesFitTheTimeGrid) {
  auto err = rig_error("  - {id: cam, type: camera, rate_hz: 200}\n");
  EXPECT_NE(err.find("vehicles[0].sensors"), std::string::npos) << err;
  EXPECT_NE(err.find("sensor 'cam' measures at 200 Hz, faster than the 100 Hz it is fed at "
                     "(time.heartbeat_s)"),
            std::string::npos)
      << err;
  err = rig_error("  - {id: imu, type: imu, rate_hz: 1000}\n");
  EXPECT_NE(err.find("faster than the 500 Hz it is fed at (time.step_s)"), std::string::npos)
      << err;
  EXPECT_EQ(rig_error("  - {id: cam, type: camera, rate_hz: 100}\n  - {id: imu, type: imu, rate_hz: 500}\n"), "");
}

// The height map's extent and heights are positions too: bounded like the world.
TEST(ConfigBounds, HeightmapExtentIsBounded) {
  const ScratchConfig cfg("heightmap_extent");
  const std::string file = (cfg.dir / "scenarios/s.yaml").string();
  auto error_for = [&](const std::string& text) {
    std::ofstream(file, std::ios::trunc) << text;
    try {
      load_scenario_config(file, {}, cfg.dir.string());
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error_for(kHeightmapScenario), "");
  auto err = error_for(replaced(kHeightmapScenario, "size_m: [200, 200]", "size_m: [1e300, 200]"));
  EXPECT_NE(err.find("terrain.heightmap.size_m: sizes must be in (0, 2e5] m"), std::string::npos)
      << err;
  err = error_for(replaced(kHeightmapScenario, "height_range_m: [0, 6]", "height_range_m: [0, 1e30]"));
  EXPECT_NE(err.find("terrain.heightmap.height_range_m"), std::string::npos) << err;
  err = error_for(replaced(kHeightmapScenario, "height_range_m: [0, 6]",
                           "height_range_m: [0, 6], centre_m: [1e12, 0]"));
  EXPECT_NE(err.find("terrain.heightmap.centre_m"), std::string::npos) << err;
}
