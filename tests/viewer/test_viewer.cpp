// The viewer's parts without a browser: the scene document, the live state's latest-only
// bookkeeping, and the HTTP/WebSocket server (civetweb's own client and plain sockets talk to
// it).
#include <arpa/inet.h>
#include <civetweb.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <numbers>
#include <thread>

#include "scenario/scenario.hpp"
#include "viewer/live_state.hpp"
#include "viewer/scene.hpp"
#include "viewer/viewer_server.hpp"

namespace fs = std::filesystem;
using namespace syndds;

namespace {

const std::string kConfig = SYNDDS_TEST_CONFIG_DIR;

proto::VehicleStateMsg state(const std::string& id, std::int64_t frame, double x) {
  proto::VehicleStateMsg s;
  s.vehicle_id = id;
  s.frame = frame;
  s.sim_time_s = frame * 0.01;
  s.pose.position = Vec3(x, 0, 0.5);
  s.wheels.resize(4);
  return s;
}

std::vector<proto::TerrainVertexMsg> vertices(std::initializer_list<std::array<double, 3>> ijh) {
  std::vector<proto::TerrainVertexMsg> out;
  for (const auto& v : ijh) {
    proto::TerrainVertexMsg m;
    m.i = static_cast<std::int32_t>(v[0]);
    m.j = static_cast<std::int32_t>(v[1]);
    m.height = v[2];
    out.push_back(m);
  }
  return out;
}

nlohmann::json update(viewer::LiveState& live, viewer::Cursor& c, std::size_t max = 1000,
                      bool* more = nullptr) {
  return nlohmann::json::parse(live.update(c, max, more));
}

// A radar scan of `sensor` on `vehicle` at stamp time `t`, the radar at `pose`; detections
// (x, y, z in the sensor frame, radial speed, strength).
proto::RadarScanMsg radar_scan(const std::string& vehicle, const std::string& sensor, double t,
                               const Pose& pose,
                               std::initializer_list<std::array<float, 5>> detections) {
  proto::RadarScanMsg m;
  m.vehicle_id = vehicle;
  m.stamp.sensor_id = sensor;
  m.stamp.time_s = t;
  m.frame = static_cast<std::int64_t>(std::lround(t / 0.01)) + 5;
  m.pose = pose;
  for (const auto& d : detections) {
    proto::RadarDetectionMsg r;
    r.x = d[0];
    r.y = d[1];
    r.z = d[2];
    r.range_m = std::hypot(d[0], d[1], d[2]);
    r.radial_speed_mps = d[3];
    r.strength_db = d[4];
    m.detections.push_back(r);
  }
  return m;
}

void expect_at(const nlohmann::json& d, double x, double y, double z) {
  EXPECT_NEAR(d["at"][0].get<double>(), x, 1e-5) << d;
  EXPECT_NEAR(d["at"][1].get<double>(), y, 1e-5) << d;
  EXPECT_NEAR(d["at"][2].get<double>(), z, 1e-5) << d;
}

}  // namespace

TEST(Scene, DescribesTheDefaultScenarioCompletelyAndTheSameEveryTime) {
  const auto s = scenario::load_scenario(kConfig + "/scenarios/default.yaml", {}, kConfig);
  const auto scene = viewer::scene_json(s);
  EXPECT_EQ(scene["format"], viewer::kSceneFormat);
  ASSERT_EQ(scene["vehicles"].size(), s.vehicles.size());
  for (std::size_t k = 0; k < s.vehicles.size(); ++k) {
    const auto& v = scene["vehicles"][k];
    EXPECT_EQ(v["id"], s.vehicles[k].id);
    EXPECT_EQ(v["wheel_positions"].size(), 4u);
    EXPECT_DOUBLE_EQ(v["wheel_radius"].get<double>(), s.vehicles[k].params.wheels.radius_m);
    EXPECT_EQ(v["path"].size(), s.vehicles[k].controller.waypoints.size());
    // The sensors' body boxes (hull, deck, cabin), inside the chassis box.
    ASSERT_EQ(v["body_boxes"].size(), 3u);
    const auto& shape = s.vehicles[k].params.chassis;
    for (const auto& b : v["body_boxes"]) {
      for (int a = 0; a < 3; ++a) {
        const double c = b["centre"][a].get<double>(), h = b["half_extents"][a].get<double>();
        EXPECT_GT(h, 0.0);
        EXPECT_GE(c - h, shape.box_centre_m[a] - shape.half_extents_m[a] - 1e-9);
        EXPECT_LE(c + h, shape.box_centre_m[a] + shape.half_extents_m[a] + 1e-9);
      }
    }
  }
  EXPECT_EQ(scene["obstacles"].size(), s.obstacles.size());
  EXPECT_TRUE(scene["soil"].is_null());
  // Every start, waypoint and obstacle is inside the terrain drawn.
  const auto& t = scene["terrain"];
  for (const auto& v : s.vehicles) {
    for (const auto& w : v.controller.waypoints) {
      EXPECT_GE(w.x(), t["x_min"].get<double>());
      EXPECT_LE(w.x(), t["x_max"].get<double>());
      EXPECT_GE(w.y(), t["y_min"].get<double>());
      EXPECT_LE(w.y(), t["y_max"].get<double>());
    }
  }
  EXPECT_EQ(t["heights"].size(), t["nx"].get<std::size_t>() * t["ny"].get<std::size_t>());
  EXPECT_EQ(viewer::scene_json(s).dump(), scene.dump());
}

TEST(Scene, GivesTheSoilGridAndTheHillsHeights) {
  const auto scm = scenario::load_scenario(kConfig + "/scenarios/scm_crossing.yaml", {}, kConfig);
  const auto soil = viewer::scene_json(scm)["soil"];
  ASSERT_TRUE(soil.is_object());
  EXPECT_DOUBLE_EQ(soil["spacing_m"].get<double>(), scm.terrain.scm.grid.spacing_m);
  EXPECT_LT(soil["i_min"].get<std::int64_t>(), soil["i_max"].get<std::int64_t>());
  const auto hills = scenario::load_scenario(kConfig + "/scenarios/hills.yaml", {}, kConfig);
  const auto t = viewer::scene_json(hills)["terrain"];
  EXPECT_EQ(t["nx"], viewer::kMaxTerrainSamples);
  const auto& h = t["heights"];
  const auto [lo, hi] = std::minmax_element(h.begin(), h.end());
  EXPECT_GT(hi->get<double>() - lo->get<double>(), 1.0);  // the hills are drawn
}

TEST(LiveState, AConnectionGetsOnlyTheNewestStateOfEachVehicle) {
  viewer::LiveState live;
  viewer::Cursor c;
  for (int f = 0; f < 10; ++f) live.on_vehicle_state(state("a", f, f));
  live.on_vehicle_state(state("a", 3, 99));  // older than what is held: ignored
  auto u = update(live, c);
  ASSERT_EQ(u["vehicles"].size(), 1u);
  EXPECT_EQ(u["vehicles"][0]["frame"], 9);
  EXPECT_DOUBLE_EQ(u["vehicles"][0]["pose"][0].get<double>(), 9.0);
  EXPECT_EQ(u["vehicles"][0]["wheels"].size(), 4u);
  EXPECT_TRUE(update(live, c)["vehicles"].empty());  // nothing new
  live.on_vehicle_state(state("b", 10, 1));
  u = update(live, c);
  ASSERT_EQ(u["vehicles"].size(), 1u);
  EXPECT_EQ(u["vehicles"][0]["id"], "b");
}

TEST(LiveState, ContactMarksReachEveryConnectionOnceAndStayBounded) {
  viewer::LiveState live;
  viewer::Cursor early, late;
  proto::CollisionEventMsg e;
  e.vehicle_id = "a";
  e.other_vehicle_id = "b";
  e.frame = 7;
  e.position = Vec3(1.0, 2.0, 0.5);
  live.on_collision(e);
  EXPECT_TRUE(live.has_news(early));
  auto u = update(live, early);
  ASSERT_EQ(u["contacts"].size(), 1u);
  EXPECT_EQ(u["contacts"][0]["with"], "b");
  EXPECT_EQ(u["contacts"][0]["vehicle_contact"], true);
  EXPECT_DOUBLE_EQ(u["contacts"][0]["at"][1].get<double>(), 2.0);
  EXPECT_TRUE(update(live, early)["contacts"].empty());  // sent once
  for (std::size_t k = 0; k < 2 * viewer::LiveState::kMaxContactMarks; ++k) {
    e.other_vehicle_id.clear();
    e.obstacle_id = "rock" + std::to_string(k);
    live.on_collision(e);
  }
  u = update(live, late);  // a late connection gets the newest marks, bounded
  ASSERT_EQ(u["contacts"].size(), viewer::LiveState::kMaxContactMarks);
  EXPECT_EQ(u["contacts"].back()["with"],
            "rock" + std::to_string(2 * viewer::LiveState::kMaxContactMarks - 1));
  EXPECT_EQ(u["contacts"].back()["vehicle_contact"], false);
}

TEST(LiveState, KeepsTheNewestRadarScanOfEachSensorWithItsDetectionsInTheWorld) {
  viewer::LiveState live;
  viewer::Cursor c;
  // The radar at (10, 20, 1) turned 90 degrees left: its x (forward) is the world's y, its y
  // (left) the world's -x.
  Pose yawed;
  yawed.position = Vec3(10, 20, 1);
  yawed.orientation = Quat(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()));
  live.on_radar(radar_scan("a", "front", 0.05, yawed, {{5, 0, 0, -3, -40}, {0, 2, 0.5, 4, -60}}));
  EXPECT_TRUE(live.has_news(c));
  auto u = update(live, c);
  ASSERT_EQ(u["radar"].size(), 1u);
  auto scan = u["radar"][0];
  EXPECT_EQ(scan["vehicle"], "a");
  EXPECT_EQ(scan["sensor"], "front");
  EXPECT_DOUBLE_EQ(scan["time_s"].get<double>(), 0.05);
  ASSERT_EQ(scan["detections"].size(), 2u);
  expect_at(scan["detections"][0], 10, 25, 1);
  expect_at(scan["detections"][1], 8, 20, 1.5);
  EXPECT_DOUBLE_EQ(scan["detections"][0]["radial_speed_mps"].get<double>(), -3.0);
  EXPECT_DOUBLE_EQ(scan["detections"][1]["radial_speed_mps"].get<double>(), 4.0);
  EXPECT_DOUBLE_EQ(scan["detections"][0]["strength_db"].get<double>(), -40.0);
  EXPECT_FALSE(live.has_news(c));
  EXPECT_TRUE(update(live, c)["radar"].empty());  // sent once

  // An older scan of the same radar changes nothing; a newer one replaces the scan held.
  live.on_radar(radar_scan("a", "front", 0.0, yawed, {{1, 1, 1, 0, 0}}));
  EXPECT_FALSE(live.has_news(c));
  // Upside down (half a turn about x) and moved: y and z change sign.
  Pose rolled;
  rolled.position = Vec3(-3, 4, 2);
  rolled.orientation = Quat(Eigen::AngleAxisd(std::numbers::pi, Vec3::UnitX()));
  live.on_radar(radar_scan("a", "front", 0.10, rolled, {{7, 1, 0.5, 2, -50}}));
  u = update(live, c);
  ASSERT_EQ(u["radar"].size(), 1u);
  EXPECT_DOUBLE_EQ(u["radar"][0]["time_s"].get<double>(), 0.10);
  ASSERT_EQ(u["radar"][0]["detections"].size(), 1u);
  expect_at(u["radar"][0]["detections"][0], 4, 3, 1.5);
  // A scan that saw nothing clears that radar's detections.
  live.on_radar(radar_scan("a", "front", 0.15, rolled, {}));
  u = update(live, c);
  ASSERT_EQ(u["radar"].size(), 1u);
  EXPECT_TRUE(u["radar"][0]["detections"].empty());

  // Another radar of the same vehicle and one of another vehicle: a scan each; only the one
  // that changed is sent, and a connection opened later gets every radar's newest scan.
  live.on_radar(radar_scan("a", "rear", 0.05, yawed, {{2, 0, 0, 1, -30}}));
  live.on_radar(radar_scan("b", "front", 0.05, yawed, {{3, 0, 0, -1, -30}}));
  EXPECT_EQ(live.radar_scans(), 3u);
  EXPECT_EQ(update(live, c)["radar"].size(), 2u);
  live.on_radar(radar_scan("b", "front", 0.10, yawed, {{4, 0, 0, -1, -30}}));
  u = update(live, c);
  ASSERT_EQ(u["radar"].size(), 1u);
  EXPECT_EQ(u["radar"][0]["vehicle"], "b");
  expect_at(u["radar"][0]["detections"][0], 10, 24, 1);
  viewer::Cursor late;
  EXPECT_EQ(update(live, late)["radar"].size(), 3u);
}

TEST(LiveState, RadarScansStayBoundedInSensorsAndDetections) {
  viewer::LiveState live;
  Pose at_origin;
  for (std::size_t k = 0; k < 2 * viewer::LiveState::kMaxRadarSensors; ++k) {
    std::string vehicle = "v";  // not "v" + to_string(k): GCC 12 warns wrongly (-Wrestrict)
    vehicle += std::to_string(k);
    live.on_radar(radar_scan(vehicle, "front", 0.05, at_origin, {{1, 0, 0, 0, 0}}));
  }
  EXPECT_EQ(live.radar_scans(), viewer::LiveState::kMaxRadarSensors);
  // A scan with more detections than are kept: the first ones (the nearest, as a scan lists
  // them by range).
  proto::RadarScanMsg many = radar_scan("v0", "front", 0.10, at_origin, {});
  for (std::size_t k = 0; k < 2 * viewer::LiveState::kMaxRadarDetections; ++k) {
    proto::RadarDetectionMsg d;
    d.x = static_cast<float>(k + 1);
    d.range_m = d.x;
    many.detections.push_back(d);
  }
  live.on_radar(many);
  viewer::Cursor c;
  const auto u = update(live, c);
  ASSERT_EQ(u["radar"].size(), viewer::LiveState::kMaxRadarSensors);
  std::size_t largest = 0;
  for (const auto& scan : u["radar"]) {
    largest = std::max(largest, scan["detections"].size());
    if (scan["vehicle"] != "v0") continue;
    ASSERT_EQ(scan["detections"].size(), viewer::LiveState::kMaxRadarDetections);
    expect_at(scan["detections"].back(), viewer::LiveState::kMaxRadarDetections, 0, 0);
  }
  EXPECT_EQ(largest, viewer::LiveState::kMaxRadarDetections);
}

TEST(LiveState, ASlowConnectionGetsEachSoilVertexOnceWithItsNewestHeight) {
  viewer::LiveState live;
  viewer::Cursor fast, slow;
  for (int round = 0; round < 50; ++round) {
    live.on_terrain(vertices({{1, 1, -0.01 * round}, {2, 1, -0.02 * round}}));
    (void)update(live, fast);
  }
  auto u = update(live, slow);
  ASSERT_EQ(u["soil"].size(), 2u);
  std::map<int, double> h;
  for (const auto& v : u["soil"]) h[v[0].get<int>()] = v[2].get<double>();
  EXPECT_DOUBLE_EQ(h[1], -0.49);
  EXPECT_DOUBLE_EQ(h[2], -0.98);
  EXPECT_TRUE(update(live, slow)["soil"].empty());
  EXPECT_TRUE(update(live, fast)["soil"].empty());
}

TEST(LiveState, TheChangeLogStaysBoundedAndCompactionLosesNothing) {
  viewer::LiveState live;
  viewer::Cursor early;
  live.on_terrain(vertices({{0, 0, 1.0}}));
  (void)update(live, early);  // has seen the first change only
  for (int round = 0; round < 2000; ++round) {
    live.on_terrain(vertices({{0, 0, 2.0 + round}, {5, 5, 3.0 + round}, {7, 1, 4.0}}));
  }
  EXPECT_LE(live.soil_log_size(), 2 * live.soil_vertices() + 4096 + 3);
  const auto u = update(live, early);
  std::map<int, double> h;
  for (const auto& v : u["soil"]) h[v[0].get<int>()] = v[2].get<double>();
  EXPECT_EQ(h.size(), 3u);
  EXPECT_DOUBLE_EQ(h[0], 2001.0);
  EXPECT_DOUBLE_EQ(h[5], 2002.0);
  EXPECT_DOUBLE_EQ(h[7], 4.0);
}

TEST(LiveState, LargeSoilChangesAreSentInPartsThatAddUp) {
  viewer::LiveState live;
  std::vector<proto::TerrainVertexMsg> many;
  for (int i = 0; i < 250; ++i) many.push_back(vertices({{double(i), 0, -0.1}})[0]);
  live.on_terrain(many);
  viewer::Cursor c;
  std::size_t total = 0, parts = 0;
  bool more = true;
  while (more) {
    total += update(live, c, 100, &more)["soil"].size();
    ++parts;
  }
  EXPECT_EQ(total, 250u);
  EXPECT_EQ(parts, 3u);
}

TEST(LiveState, RealTimeFactorMembersAndTheEnd) {
  viewer::LiveState live;
  viewer::Cursor c;
  EXPECT_TRUE(update(live, c)["real_time_factor"].is_null());
  for (int f = 1; f <= 100; ++f) live.on_frame(f, f * 0.01, 10.0 + f * 0.02);  // 2x slower
  auto u = update(live, c);
  EXPECT_NEAR(u["real_time_factor"].get<double>(), 2.0, 1e-9);
  EXPECT_EQ(u["frame"], 100);
  proto::MemberAnnounceMsg m;
  m.member_id = "vehicle/a";
  m.host = "h1";
  m.pid = 42;
  live.on_member(m, 0.0);
  u = update(live, c);
  ASSERT_EQ(u["members"].size(), 1u);
  EXPECT_EQ(u["members"][0]["kind"], "vehicle");
  live.on_member(m, 1.0);  // the same again: no new list
  EXPECT_FALSE(update(live, c).contains("members"));
  EXPECT_FALSE(live.ended());
  proto::RunControlMsg end;
  end.status = proto::RunStatus::aborted;
  end.reason = "member x lost";
  live.on_run_end(end);
  u = update(live, c);
  EXPECT_EQ(u["status"], "aborted");
  EXPECT_EQ(u["reason"], "member x lost");
  EXPECT_TRUE(live.ended());
}

TEST(LiveState, NothingNewMeansNothingToSend) {
  viewer::LiveState live;
  viewer::Cursor c;
  EXPECT_TRUE(live.has_news(c));  // the first update (status, empty world)
  update(live, c);
  EXPECT_FALSE(live.has_news(c));
  live.on_frame(1, 0.01, 1.0);
  EXPECT_TRUE(live.has_news(c));
  update(live, c);
  EXPECT_FALSE(live.has_news(c));
  live.on_vehicle_state(state("a", 1, 1));
  EXPECT_TRUE(live.has_news(c));
  update(live, c);
  live.on_terrain(vertices({{3, 4, -0.01}}));
  EXPECT_TRUE(live.has_news(c));
  update(live, c);
  proto::MemberAnnounceMsg m;
  m.member_id = "vehicle/a";
  live.on_member(m, 0.0);
  EXPECT_TRUE(live.has_news(c));
  update(live, c);
  live.on_member(m, 1.0);  // the same member again
  EXPECT_FALSE(live.has_news(c));
  live.on_radar(radar_scan("a", "front", 0.0, Pose{}, {}));
  EXPECT_TRUE(live.has_news(c));
  update(live, c);
  EXPECT_FALSE(live.has_news(c));
  live.on_run_end(proto::RunControlMsg{});
  EXPECT_TRUE(live.has_news(c));
  update(live, c);
  EXPECT_FALSE(live.has_news(c));
  viewer::Cursor late;  // a connection opened later gets everything
  EXPECT_TRUE(live.has_news(late));
}

TEST(ViewerFiles, OnlyRegularFilesInsideTheRootAreServed) {
  const fs::path root = fs::temp_directory_path() / ("syndds_viewer_files_" + std::to_string(::getpid()));
  fs::create_directories(root / "sensors" / "a");
  std::ofstream(root / "vehicles.csv") << "x\n";
  std::ofstream(root / "sensors" / "a" / "frames.csv") << "y\n";
  fs::create_symlink("/etc/hostname", root / "link");
  EXPECT_EQ(viewer::file_inside(root, "vehicles.csv"), fs::canonical(root / "vehicles.csv"));
  EXPECT_FALSE(viewer::file_inside(root, "sensors/a/frames.csv").empty());
  // Out and back in is still inside.
  EXPECT_FALSE(viewer::file_inside(root, "../" + root.filename().string() + "/vehicles.csv").empty());
  EXPECT_TRUE(viewer::file_inside(root, "../../../../../../etc/passwd").empty());
  EXPECT_TRUE(viewer::file_inside(root, "/etc/passwd").empty());  // taken as root/etc/passwd
  EXPECT_TRUE(viewer::file_inside(root, "link").empty());   // leads outside
  EXPECT_TRUE(viewer::file_inside(root, "sensors").empty());  // a folder
  EXPECT_TRUE(viewer::file_inside(root, "missing.csv").empty());
  fs::remove_all(root);
}

namespace {

// A web root with a page and a stand-in of the three package (the server checks both exist).
struct WebFixture {
  fs::path dir = fs::temp_directory_path() / ("syndds_viewer_web_" + std::to_string(::getpid()));
  WebFixture() {
    fs::create_directories(dir / "web");
    fs::create_directories(dir / "three" / "build");
    fs::create_directories(dir / "run");
    fs::create_directories(dir / "meshes");
    std::ofstream(dir / "meshes" / "rock.obj") << "o rock\n";
    std::ofstream(dir / "meshes" / "meshes.mtl") << "newmtl rock\n";
    std::ofstream(dir / "meshes" / "notes.txt") << "not a mesh\n";
    std::ofstream(dir / "web" / "index.html") << "<html>page</html>";
    std::ofstream(dir / "web" / "viewer.js") << "// the page's script";
    std::ofstream(dir / "web" / "style.css") << "body {}";
    std::ofstream(dir / "web" / "package.json") << "{}";
    // What npm installs beside the page: not the page's, never served from here.
    fs::create_directories(dir / "web" / "node_modules" / "three" / "build");
    fs::create_directories(dir / "web" / "node_modules" / "other");
    std::ofstream(dir / "web" / "node_modules" / "three" / "package.json") << "{}";
    std::ofstream(dir / "web" / "node_modules" / "three" / "build" / "three.module.js") << "x";
    std::ofstream(dir / "web" / "node_modules" / "other" / "index.js") << "secret";
    std::ofstream(dir / "three" / "build" / "three.module.js") << "export const x = 1;";
    std::ofstream(dir / "three" / "package.json") << "{}";
    fs::create_directories(dir / "three" / "examples" / "jsm" / "controls");
    std::ofstream(dir / "three" / "examples" / "jsm" / "controls" / "OrbitControls.js") << "y";
    std::ofstream(dir / "three" / "examples" / "jsm" / "README.md") << "not a module";
    std::ofstream(dir / "run" / "vehicles.csv") << "frame\n0\n";
  }
  ~WebFixture() { fs::remove_all(dir); }
  viewer::ServerOptions options(bool replay) const {
    viewer::ServerOptions o;
    o.port = 0;
    o.web_root = dir / "web";
    o.three_dir = dir / "three";
    if (replay) o.run_dir = dir / "run";
    o.mesh_dir = dir / "meshes";
    o.update_hz = 100;
    return o;
  }
};

struct Response {
  int status = 0;
  std::string body;
  std::map<std::string, std::string> headers;  // names in lower case
};

// `path` with `headers` (each ending in \r\n; by default a browser's Host for the port).
Response request(int port, const std::string& path, std::string headers = "") {
  if (headers.empty()) headers = "Host: 127.0.0.1:" + std::to_string(port) + "\r\n";
  char err[256] = {};
  mg_connection* c = mg_download("127.0.0.1", port, 0, err, sizeof err, "GET %s HTTP/1.1\r\n%s\r\n",
                                 path.c_str(), headers.c_str());
  if (!c) return {0, err, {}};
  Response r;
  const mg_response_info* info = mg_get_response_info(c);
  r.status = info->status_code;
  for (int k = 0; k < info->num_headers; ++k) {
    std::string name = info->http_headers[k].name;
    for (char& ch : name) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    r.headers[name] = info->http_headers[k].value;
  }
  char buf[4096];
  int n;
  // A 101 (WebSocket) answer has no body: the connection stays open.
  while (r.status != 101 && (n = mg_read(c, buf, sizeof buf)) > 0) r.body.append(buf, n);
  mg_close_connection(c);
  return r;
}

// GET `path` as a browser on 127.0.0.1 asks for it: status and body.
std::pair<int, std::string> get(int port, const std::string& path) {
  const Response r = request(port, path);
  return {r.status, r.body};
}

}  // namespace

TEST(ViewerServer, ServesThePageTheSceneTheRunAndNothingElse) {
  WebFixture web;
  viewer::ViewerServer server(web.options(true), R"({"format":1})", nullptr, nullptr);
  ASSERT_GT(server.port(), 0);
  EXPECT_EQ(get(server.port(), "/").second, "<html>page</html>");
  EXPECT_EQ(get(server.port(), "/api/scene").second, R"({"format":1})");
  const auto info = nlohmann::json::parse(get(server.port(), "/api/info").second);
  EXPECT_EQ(info["mode"], "replay");
  EXPECT_EQ(info["run_files"], nlohmann::json::array({"vehicles.csv"}));
  EXPECT_EQ(get(server.port(), "/run/vehicles.csv"), std::make_pair(200, std::string("frame\n0\n")));
  EXPECT_EQ(get(server.port(), "/vendor/three/build/three.module.js").first, 200);
  EXPECT_EQ(get(server.port(), "/vendor/three/package.json").first, 404);  // not the module
  EXPECT_EQ(get(server.port(), "/run/../web/index.html").first, 404);
  EXPECT_EQ(get(server.port(), "/run/%2e%2e/three/package.json").first, 404);
  EXPECT_EQ(get(server.port(), "/run/missing.csv").first, 404);
  EXPECT_EQ(get(server.port(), "/api/nothing").first, 404);
}

TEST(ViewerServer, ServesTheSensorsMeshesAndTheirMaterialsOnly) {
  WebFixture web;
  viewer::ViewerServer server(web.options(true), "{}", nullptr, nullptr);
  const auto info = nlohmann::json::parse(get(server.port(), "/api/info").second);
  EXPECT_EQ(info["meshes"], nlohmann::json::array({"rock"}));
  EXPECT_EQ(get(server.port(), "/meshes/rock.obj"), std::make_pair(200, std::string("o rock\n")));
  EXPECT_EQ(get(server.port(), "/meshes/meshes.mtl").first, 200);
  EXPECT_EQ(get(server.port(), "/meshes/notes.txt").first, 404);       // not a mesh file
  // Only files directly in the folder, no links out of it.
  fs::create_directories(web.dir / "meshes" / "sub");
  std::ofstream(web.dir / "meshes" / "sub" / "deep.obj") << "o deep\n";
  EXPECT_EQ(get(server.port(), "/meshes/sub/deep.obj").first, 404);
  std::ofstream(web.dir / "outside.obj") << "o outside\n";
  fs::create_symlink(web.dir / "outside.obj", web.dir / "meshes" / "link.obj");
  EXPECT_EQ(get(server.port(), "/meshes/link.obj").first, 404);
  EXPECT_EQ(get(server.port(), "/meshes/%2e%2e%2fweb%2findex.obj").first, 404);
  EXPECT_EQ(get(server.port(), "/meshes/tree.obj").first, 404);        // none
  // Without a mesh folder: none listed, none served (the page draws primitives).
  auto o = web.options(true);
  o.mesh_dir.clear();
  viewer::ViewerServer plain(o, "{}", nullptr, nullptr);
  EXPECT_EQ(nlohmann::json::parse(get(plain.port(), "/api/info").second)["meshes"],
            nlohmann::json::array());
  EXPECT_EQ(get(plain.port(), "/meshes/rock.obj").first, 404);
}

TEST(ViewerServer, RefusesAWebRootWithoutThePage) {
  WebFixture web;
  auto o = web.options(false);
  o.web_root = web.dir / "three";
  EXPECT_THROW(viewer::ViewerServer(o, "{}", nullptr, nullptr), ConfigError);
  o = web.options(false);
  o.three_dir = web.dir / "web";
  EXPECT_THROW(viewer::ViewerServer(o, "{}", nullptr, nullptr), ConfigError);
}

TEST(ViewerServer, ServesThePagesFilesAndThreesModulesButNothingElseOfNodeModules) {
  WebFixture web;
  viewer::ViewerServer server(web.options(true), "{}", nullptr, nullptr);
  const int p = server.port();
  EXPECT_EQ(get(p, "/index.html"), std::make_pair(200, std::string("<html>page</html>")));
  EXPECT_EQ(get(p, "/viewer.js").first, 200);
  EXPECT_EQ(get(p, "/style.css").first, 200);
  // What the page imports (index.html's import map): three's build and its add-ons.
  EXPECT_EQ(get(p, "/vendor/three/build/three.module.js").first, 200);
  EXPECT_EQ(get(p, "/vendor/three/examples/jsm/controls/OrbitControls.js").first, 200);
  EXPECT_EQ(get(p, "/vendor/three/examples/jsm/README.md").first, 404);  // not a module
  EXPECT_EQ(get(p, "/vendor/three/package.json").first, 404);
  // Nothing npm installed is served as it lies, nor the page folder's package files.
  for (const char* path :
       {"/package.json", "/node_modules/three/package.json", "/node_modules/other/index.js",
        "/node_modules/three/build/three.module.js", "/node_modules/", "/node_modules"}) {
    EXPECT_EQ(get(p, path).first, 404) << path;
  }
  // Out of the served folders, plain and encoded.
  for (const char* path :
       {"/vendor/three/build/../package.json", "/vendor/three/build/%2e%2e/package.json",
        "/vendor/three/build/%2e%2e%2f%2e%2e%2f%2e%2e%2fweb%2fpackage.json",
        "/vendor/three/examples/jsm/../../../web/node_modules/other/index.js",
        "/node_modules/three/%2e%2e/%2e%2e/package.json", "/%2e%2e/three/package.json",
        "/..%2fthree%2fpackage.json", "/vendor/three/build/%2fetc%2fpasswd",
        "/node_modules%2fother%2findex.js"}) {
    EXPECT_EQ(get(p, path).first, 404) << path;
  }
}

namespace {

struct WsInbox {
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<std::string> texts;
  std::size_t binaries = 0;
  bool closed = false;
};

int ws_data(mg_connection*, int bits, char* data, std::size_t len, void* user) {
  auto* in = static_cast<WsInbox*>(user);
  std::lock_guard lock(in->mutex);
  if ((bits & 0x0f) == MG_WEBSOCKET_OPCODE_TEXT) in->texts.emplace_back(data, len);
  if ((bits & 0x0f) == MG_WEBSOCKET_OPCODE_BINARY) ++in->binaries;
  in->cv.notify_all();
  return 1;
}

void ws_close(const mg_connection*, void* user) {
  auto* in = static_cast<WsInbox*>(user);
  std::lock_guard lock(in->mutex);
  in->closed = true;
  in->cv.notify_all();
}

}  // namespace

TEST(ViewerServer, StreamsTheSceneThenLiveUpdatesAndTheSelectedCamera) {
  WebFixture web;
  viewer::LiveState live;
  viewer::SensorStore sensors;
  viewer::ViewerServer server(web.options(false), R"({"format":1})", &live, &sensors);
  WsInbox inbox;
  char err[256] = {};
  mg_connection* c = mg_connect_websocket_client("127.0.0.1", server.port(), 0, err, sizeof err,
                                                 "/live", nullptr, ws_data, ws_close, &inbox);
  ASSERT_NE(c, nullptr) << err;
  const std::string select = R"({"select":"a"})";
  mg_websocket_client_write(c, MG_WEBSOCKET_OPCODE_TEXT, select.data(), select.size());
  live.on_vehicle_state(state("a", 5, 1.0));
  live.on_terrain(vertices({{3, 4, -0.05}}));
  sensors.set_image("a", {"cam", 5, std::string("\xff\xd8jpeg", 6), 0});
  sensors.set_image("b", {"cam", 5, "other vehicle", 0});
  const auto got = [&](auto pred) {
    std::unique_lock lock(inbox.mutex);
    return inbox.cv.wait_for(lock, std::chrono::seconds(10), [&] { return pred(); });
  };
  ASSERT_TRUE(got([&] {
    bool vehicle = false, soil = false;
    for (const auto& t : inbox.texts) {
      const auto m = nlohmann::json::parse(t);
      if (m["type"] != "update") continue;
      vehicle = vehicle || !m["vehicles"].empty();
      soil = soil || !m["soil"].empty();
    }
    return vehicle && soil && inbox.binaries >= 1;
  }));
  {
    std::lock_guard lock(inbox.mutex);
    EXPECT_EQ(nlohmann::json::parse(inbox.texts.front())["type"], "scene");
    EXPECT_EQ(inbox.binaries, 1u);  // vehicle a's image, once
  }
  EXPECT_EQ(server.connections(), 1u);
  mg_close_connection(c);
  for (int k = 0; k < 100 && server.connections() > 0; ++k) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(server.connections(), 0u);
}

TEST(ViewerAccess, AnswersTheBoundAddressAndLocalhostAtTheBoundPortOnly) {
  const viewer::AccessList access(viewer::parse_bind("127.0.0.1"), {}, {});
  for (const char* host : {"127.0.0.1:8080", "localhost:8080", "LocalHost:8080", "[::1]:8080",
                           "[0:0:0:0:0:0:0:1]:8080", "localhost"}) {
    EXPECT_TRUE(access.host_allowed(host, 8080)) << host;
  }
  // Another site's name (DNS rebinding sends it), another port, nonsense.
  for (const char* host :
       {"evil.example:8080", "evil.example", "localhost:8081", "127.0.0.2:8080",
        "localhost.evil.example:8080", "", ":8080", "localhost:", "localhost:0", "localhost:99999",
        "[::1", "[evil]:8080", "local host:8080", "localhost:80a"}) {
    EXPECT_FALSE(access.host_allowed(host, 8080)) << host;
  }
  EXPECT_TRUE(access.origin_allowed("http://127.0.0.1:8080", 8080));
  EXPECT_TRUE(access.origin_allowed("http://localhost:8080", 8080));
  EXPECT_TRUE(access.origin_allowed("http://[::1]:8080", 8080));
  for (const char* origin :
       {"http://evil.example", "http://localhost:3000", "https://127.0.0.1:8080",
        "http://localhost", "null", "file://", "http://127.0.0.1:8080/x", ""}) {
    EXPECT_FALSE(access.origin_allowed(origin, 8080)) << origin;
  }
}

TEST(ViewerAccess, AddsTheHostsAndOriginsGivenAndRejectsMalformedOnesByOption) {
  const viewer::AccessList access(viewer::parse_bind("127.0.0.1"),
                                  {"viewer.lab", "Tunnel.lab:9000", "[::2]"},
                                  {"https://proxy.example", "http://other.lab:81/"});
  EXPECT_TRUE(access.host_allowed("viewer.lab:8080", 8080));
  EXPECT_FALSE(access.host_allowed("viewer.lab:9000", 8080));
  EXPECT_TRUE(access.host_allowed("tunnel.lab:9000", 8080));
  EXPECT_FALSE(access.host_allowed("tunnel.lab:8080", 8080));
  EXPECT_TRUE(access.host_allowed("[::2]:8080", 8080));
  // The pages of the allowed hosts, and the origins given exactly (scheme, name and port).
  EXPECT_TRUE(access.origin_allowed("http://viewer.lab:8080", 8080));
  EXPECT_TRUE(access.origin_allowed("http://tunnel.lab:9000", 8080));
  EXPECT_TRUE(access.origin_allowed("https://proxy.example", 8080));
  EXPECT_TRUE(access.origin_allowed("https://proxy.example:443", 8080));
  EXPECT_FALSE(access.origin_allowed("http://proxy.example", 8080));
  EXPECT_TRUE(access.origin_allowed("http://other.lab:81", 8080));
  EXPECT_FALSE(access.origin_allowed("http://other.lab", 8080));
  EXPECT_FALSE(access.host_allowed("proxy.example", 8080));  // an origin is not a host
  const auto refused = [](std::vector<std::string> hosts, std::vector<std::string> origins,
                          const std::string& option) {
    try {
      viewer::AccessList(viewer::parse_bind("127.0.0.1"), hosts, origins);
    } catch (const ConfigError& e) {
      return std::string(e.what()).find(option) != std::string::npos;
    }
    return false;
  };
  for (const char* bad : {"", "::1", "a b", "host:port", "host:0", "http://host", "[::1]x"}) {
    EXPECT_TRUE(refused({bad}, {}, "--allow-host")) << bad;
  }
  for (const char* bad :
       {"", "host", "ftp://host", "http://host/path", "http://", "null", "http://host:99999"}) {
    EXPECT_TRUE(refused({}, {bad}, "--allow-origin")) << bad;
  }
}

TEST(ViewerAccess, AWildcardAddressAnswersThisMachinesAddressesAndName) {
  const viewer::AccessList access(viewer::parse_bind("0.0.0.0"), {}, {});
  EXPECT_TRUE(access.host_allowed("127.0.0.1:8080", 8080));
  EXPECT_TRUE(access.host_allowed("localhost:8080", 8080));
  EXPECT_FALSE(access.host_allowed("0.0.0.0:8080", 8080));
  EXPECT_FALSE(access.host_allowed("evil.example:8080", 8080));
  char name[256] = {};
  ASSERT_EQ(gethostname(name, sizeof name - 1), 0);
  EXPECT_TRUE(access.host_allowed(std::string(name) + ":8080", 8080)) << name;
}

TEST(ViewerAccess, TheBindAddressIsCheckedAndNamedInErrors) {
  EXPECT_EQ(viewer::parse_bind("127.0.0.1").host, "127.0.0.1");
  EXPECT_TRUE(viewer::parse_bind("0.0.0.0").wildcard);
  EXPECT_EQ(viewer::parse_bind("LocalHost").host, "localhost");
  for (const char* bad : {"", "[127.0.0.1]", "not an address", "1.2.3.4:80", "[::1"}) {
    try {
      viewer::parse_bind(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("--bind"), std::string::npos) << e.what();
    }
  }
  for (const char* v6 : {"::1", "[::1]", "::"}) {
    if (viewer::civetweb_has_ipv6()) {
      EXPECT_TRUE(viewer::parse_bind(v6).ipv6) << v6;
    } else {
      // Named: the option, and why it cannot work with this library.
      try {
        viewer::parse_bind(v6);
        ADD_FAILURE() << v6 << " accepted without IPv6 in civetweb";
      } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("--bind"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("IPv6"), std::string::npos) << e.what();
      }
    }
  }
}

namespace {

// A WebSocket upgrade request's headers, with `host` and `origin` (none when empty).
std::string upgrade(const std::string& host, const std::string& origin = "") {
  return "Host: " + host +
         "\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
         "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n" +
         (origin.empty() ? "" : "Origin: " + origin + "\r\n");
}

// Waits (bounded) until `pred` holds.
template <class Pred>
bool eventually(Pred pred, std::chrono::milliseconds limit = std::chrono::seconds(10)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (!pred()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

}  // namespace

TEST(ViewerServer, AnswersOnlyRequestsForItsOwnHostsWithoutCorsHeaders) {
  WebFixture web;
  viewer::ViewerServer server(web.options(true), "{}", nullptr, nullptr);
  const std::string port = std::to_string(server.port());
  const auto status = [&](const std::string& path, const std::string& headers) {
    return request(server.port(), path, headers).status;
  };
  EXPECT_EQ(status("/", "Host: 127.0.0.1:" + port + "\r\n"), 200);
  EXPECT_EQ(status("/", "Host: localhost:" + port + "\r\n"), 200);
  // DNS rebinding: a page of evil.example whose name now leads here sends its own name.
  EXPECT_EQ(status("/", "Host: evil.example:" + port + "\r\n"), 403);
  EXPECT_EQ(status("/run/vehicles.csv", "Host: evil.example:" + port + "\r\n"), 403);
  EXPECT_EQ(status("/api/scene", "Host: evil.example:" + port + "\r\n"), 403);
  EXPECT_EQ(status("/run/vehicles.csv", "Host: localhost:1\r\n"), 403);
  EXPECT_EQ(status("/run/vehicles.csv", "X-None: 1\r\n"), 403);  // no Host at all
  // Another site's page asking for a run file: refused; the viewer's own page: answered, and
  // no response invites other sites to read it.
  const std::string host = "Host: 127.0.0.1:" + port + "\r\n";
  EXPECT_EQ(status("/run/vehicles.csv", host + "Origin: http://evil.example\r\n"), 403);
  EXPECT_EQ(status("/run/vehicles.csv", host + "Origin: http://127.0.0.1:1\r\n"), 403);
  const Response own = request(server.port(), "/run/vehicles.csv",
                               host + "Origin: http://127.0.0.1:" + port + "\r\n");
  EXPECT_EQ(own.status, 200);
  EXPECT_EQ(own.headers.count("access-control-allow-origin"), 0u);
  for (const char* path : {"/", "/api/info", "/vendor/three/build/three.module.js"}) {
    const Response r =
        request(server.port(), path, host + "Origin: http://127.0.0.1:" + port + "\r\n");
    EXPECT_EQ(r.status, 200) << path;
    EXPECT_EQ(r.headers.count("access-control-allow-origin"), 0u) << path;
  }
  // The names given are answered too.
  auto o = web.options(true);
  o.allow_hosts = {"viewer.lab"};
  viewer::ViewerServer named(o, "{}", nullptr, nullptr);
  const std::string nport = std::to_string(named.port());
  EXPECT_EQ(request(named.port(), "/", "Host: viewer.lab:" + nport + "\r\n").status, 200);
  EXPECT_EQ(request(named.port(), "/", "Host: evil.example:" + nport + "\r\n").status, 403);
}

TEST(ViewerServer, RefusesAWebSocketFromAnotherSitesPage) {
  WebFixture web;
  viewer::LiveState live;
  viewer::ViewerServer server(web.options(false), R"({"format":1})", &live, nullptr);
  const std::string port = std::to_string(server.port());
  const std::string host = "127.0.0.1:" + port;
  // Cross-site WebSocket hijacking: a page of another site opens the stream.
  EXPECT_EQ(request(server.port(), "/live", upgrade(host, "http://evil.example")).status, 403);
  EXPECT_EQ(request(server.port(), "/live", upgrade(host, "http://localhost:3000")).status, 403);
  EXPECT_EQ(request(server.port(), "/live", upgrade(host, "null")).status, 403);
  EXPECT_EQ(request(server.port(), "/live", upgrade("evil.example:" + port)).status, 403);
  WsInbox inbox;
  char err[256] = {};
  mg_connection* c =
      mg_connect_websocket_client("127.0.0.1", server.port(), 0, err, sizeof err, "/live",
                                  "http://evil.example", ws_data, ws_close, &inbox);
  EXPECT_EQ(c, nullptr);
  if (c) mg_close_connection(c);
  EXPECT_EQ(server.connections(), 0u);
  // The viewer's own page: its origin is the host it was loaded from.
  EXPECT_EQ(request(server.port(), "/live", upgrade(host, "http://" + host)).status, 101);
  EXPECT_EQ(
      request(server.port(), "/live", upgrade("localhost:" + port, "http://localhost:" + port))
          .status,
      101);
  c = mg_connect_websocket_client("127.0.0.1", server.port(), 0, err, sizeof err, "/live",
                                  ("http://" + host).c_str(), ws_data, ws_close, &inbox);
  ASSERT_NE(c, nullptr) << err;
  {
    std::unique_lock lock(inbox.mutex);
    ASSERT_TRUE(
        inbox.cv.wait_for(lock, std::chrono::seconds(10), [&] { return !inbox.texts.empty(); }));
    EXPECT_EQ(nlohmann::json::parse(inbox.texts.front())["type"], "scene");
  }
  mg_close_connection(c);
  // An origin the user allowed.
  auto o = web.options(false);
  o.allow_origins = {"https://proxy.example"};
  viewer::ViewerServer proxied(o, "{}", &live, nullptr);
  const std::string phost = "127.0.0.1:" + std::to_string(proxied.port());
  EXPECT_EQ(request(proxied.port(), "/live", upgrade(phost, "https://proxy.example")).status, 101);
  EXPECT_EQ(request(proxied.port(), "/live", upgrade(phost, "http://proxy.example")).status, 403);
}

TEST(ViewerServer, RefusesLivePagesBeyondItsLimitAndTakesOneWhenAnotherCloses) {
  WebFixture web;
  viewer::LiveState live;
  auto o = web.options(false);
  o.threads = 4;
  o.max_live = 2;
  viewer::ViewerServer server(o, "{}", &live, nullptr);
  std::vector<WsInbox> inboxes(3);
  std::vector<mg_connection*> open;
  char err[256] = {};
  for (int k = 0; k < 2; ++k) {
    open.push_back(mg_connect_websocket_client("127.0.0.1", server.port(), 0, err, sizeof err,
                                               "/live", nullptr, ws_data, ws_close, &inboxes[k]));
    ASSERT_NE(open.back(), nullptr) << err;
  }
  ASSERT_TRUE(eventually([&] { return server.connections() == 2; }));
  const std::string host = "127.0.0.1:" + std::to_string(server.port());
  EXPECT_EQ(request(server.port(), "/live", upgrade(host)).status, 503);
  EXPECT_EQ(get(server.port(), "/").first, 200);  // the page is still served
  mg_close_connection(open[0]);
  ASSERT_TRUE(eventually([&] { return server.connections() == 1; }));
  mg_connection* again = nullptr;
  // The slot is free once civetweb has closed the connection (just after connections() fell).
  ASSERT_TRUE(eventually([&] {
    again = mg_connect_websocket_client("127.0.0.1", server.port(), 0, err, sizeof err, "/live",
                                        nullptr, ws_data, ws_close, &inboxes[2]);
    return again != nullptr;
  }));
  mg_close_connection(again);
  mg_close_connection(open[1]);
}

namespace {

// A TCP connection to 127.0.0.1:`port` (-1 when refused).
int connect_to(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// Whether the peer closed `fd` (end of stream) by `deadline`.
bool closed_by_peer(int fd, std::chrono::steady_clock::time_point deadline) {
  char buf[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    pollfd p{fd, POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::max<long>(0, left.count())));
    if (ready <= 0) return false;
    if (::read(fd, buf, sizeof buf) <= 0) return true;
  }
}

// Reads until the peer closes or `deadline`; what was read.
std::string read_until_closed(int fd, std::chrono::steady_clock::time_point deadline) {
  std::string got;
  char buf[4096];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
        deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return got;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n <= 0) return got;
    got.append(buf, static_cast<std::size_t>(n));
  }
}

}  // namespace

TEST(ViewerServer, IdleConnectionsDoNotStarveANewRequest) {
  WebFixture web;
  viewer::LiveState live;
  const viewer::ServerOptions defaults;
  viewer::ViewerServer server(web.options(false), "{}", &live, nullptr);
  // More connections than workers, all silent: each holds a worker until it times out.
  std::vector<int> idle;
  for (int k = 0; k < defaults.threads + 4; ++k) {
    const int fd = connect_to(server.port());
    ASSERT_GE(fd, 0);
    idle.push_back(fd);
  }
  const auto start = std::chrono::steady_clock::now();
  const int fd = connect_to(server.port());
  ASSERT_GE(fd, 0);
  const std::string req =
      "GET /api/info HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(server.port()) + "\r\n\r\n";
  ASSERT_EQ(::write(fd, req.data(), req.size()), static_cast<ssize_t>(req.size()));
  // Answered once the idle ones time out: within the request timeout and a margin.
  const auto bound = std::chrono::milliseconds(defaults.request_timeout_ms + 5000);
  const std::string answer = read_until_closed(fd, start + bound);
  const auto took = std::chrono::steady_clock::now() - start;
  ::close(fd);
  EXPECT_EQ(answer.rfind("HTTP/1.1 200", 0), 0u) << "no answer within " << bound.count() << " ms";
  EXPECT_LT(took, bound);
  // The server closed idle connections to free the worker that answered: at least those queued
  // before the request (civetweb hands connections to workers in the order it accepted them).
  std::size_t closed = 0;
  const auto grace = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  for (const int i : idle) {
    closed += closed_by_peer(i, grace);
    ::close(i);
  }
  EXPECT_GE(closed, idle.size() - static_cast<std::size_t>(defaults.threads) + 1);
}

// --bind takes an IPv6 address where civetweb was built with IPv6 (it listens there), and is
// refused naming the option and the reason where it was not (Debian 12's libcivetweb): either
// way the user learns what happened, never a bare "cannot listen".
TEST(ViewerServer, BindsIpv6OrRefusesItByName) {
  WebFixture web;
  auto o = web.options(true);
  o.bind = "::1";
  if (!viewer::civetweb_has_ipv6()) {
    try {
      viewer::ViewerServer server(o, "{}", nullptr, nullptr);
      ADD_FAILURE() << "--bind ::1 accepted by a civetweb without IPv6";
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("--bind ::1"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("IPv6"), std::string::npos) << e.what();
    }
    return;
  }
  for (const char* bind : {"::1", "[::1]"}) {
    o.bind = bind;
    viewer::ViewerServer server(o, "{}", nullptr, nullptr);
    EXPECT_EQ(server.url(), "http://[::1]:" + std::to_string(server.port()) + "/");
    const int fd = ::socket(AF_INET6, SOCK_STREAM, 0);
    sockaddr_in6 a{};
    a.sin6_family = AF_INET6;
    a.sin6_port = htons(static_cast<std::uint16_t>(server.port()));
    a.sin6_addr = in6addr_loopback;
    ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0) << bind;
    const std::string req =
        "GET /run/vehicles.csv HTTP/1.1\r\nHost: [::1]:" + std::to_string(server.port()) +
        "\r\n\r\n";
    ASSERT_EQ(::write(fd, req.data(), req.size()), static_cast<ssize_t>(req.size()));
    const std::string answer =
        read_until_closed(fd, std::chrono::steady_clock::now() + std::chrono::seconds(10));
    ::close(fd);
    EXPECT_EQ(answer.rfind("HTTP/1.1 200", 0), 0u) << answer;
  }
}
