// syndds_viewer: a browser viewer of a live run (read-only DDS subscriber, never a barrier
// member) or of a recorded run directory (--replay). docs/viewer.md.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <thread>

#include "common/service_cli.hpp"
#include "dds/participant.hpp"
#include "core/error.hpp"
#include "viewer/scene.hpp"
#include "viewer/viewer_feed.hpp"
#include "viewer/viewer_server.hpp"

namespace fs = std::filesystem;
using namespace syndds;

namespace {

std::string read_whole(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw ConfigError(p.string() + ": cannot read");
  return std::string(std::istreambuf_iterator<char>(in), {});
}

fs::path default_web_root() {
  if (const char* env = std::getenv("SYNDDS_VIEWER_WEB")) return env;
  return SYNDDS_VIEWER_WEB_DIR;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"syndds viewer: watch a live run or replay a recorded one in a browser"};
  service::CommonArgs common;
  common.cpu_policy = "normal";  // it serves a browser: its answers should not wait
  service::add_common_options(app, common);
  app.get_option("scenario")->required(false)->description(
      "Scenario YAML file of the live run to watch (not with --replay)");
  std::string replay;
  viewer::ServerOptions server;
  std::string web_root, three_dir, mesh_dir, url_file;
  double exit_after_run_s = -1.0;
  app.add_option("--replay", replay, "Replay this run directory (written by the recorder)");
  app.add_option("--bind", server.bind,
                 "Address to listen on (0.0.0.0: every interface; an IPv6 address, ::1 or [::1], "
                 "needs a civetweb built with IPv6)")
      ->capture_default_str();
  app.add_option("--allow-host", server.allow_hosts,
                 "Also answer requests for this host name (NAME or NAME:PORT; repeatable). "
                 "Always answered: the --bind address, localhost, 127.0.0.1 and [::1] at --port "
                 "(docs/viewer.md)")
      ->allow_extra_args(false);
  app.add_option("--allow-origin", server.allow_origins,
                 "Also let pages of this origin (http[s]://HOST[:PORT], e.g. a reverse proxy's) "
                 "open the live WebSocket; repeatable (docs/viewer.md)")
      ->allow_extra_args(false);
  app.add_option("--port", server.port, "TCP port (0: any free port)")->capture_default_str();
  app.add_option("--web-root", web_root, "Folder with the page (default: the source tree's)");
  app.add_option("--three-dir", three_dir, "The three.js package (default: WEB_ROOT/node_modules/three)");
  app.add_option("--mesh-dir", mesh_dir,
                 "OBJ meshes of obstacles (by label) and vehicle_body.obj (default: the source "
                 "tree's config/meshes; 'none': boxes, cylinders and spheres)");
  app.add_option("--url-file", url_file, "Write the page's URL to this file once listening");
  app.add_option("--exit-after-run", exit_after_run_s,
                 "Live: exit this many seconds after the run ended (default: keep serving)");
  return service::run_service("viewer", app, argc, argv, common, [&] {
    if (replay.empty() == common.scenario_file.empty()) {
      throw ConfigError("give either a scenario (live) or --replay RUN_DIR");
    }
    server.web_root = web_root.empty() ? default_web_root() : fs::path(web_root);
    server.three_dir =
        three_dir.empty() ? server.web_root / "node_modules" / "three" : fs::path(three_dir);
    // Default: the meshes the sensor rigs use (config/meshes), so the page draws obstacles and
    // vehicle bodies with the same files.
    server.mesh_dir = mesh_dir.empty() ? fs::path(SYNDDS_VIEWER_MESH_DIR) : fs::path(mesh_dir);
    if (mesh_dir == "none") {
      server.mesh_dir.clear();
    } else if (!fs::is_directory(server.mesh_dir)) {
      throw ConfigError("--mesh-dir " + server.mesh_dir.string() + ": not a folder");
    }
    if (server.port < 0 || server.port > 65535) {
      throw ConfigError("--port " + std::to_string(server.port) + ": expected 0..65535");
    }
    viewer::LiveState live;
    viewer::SensorStore sensors;
    std::unique_ptr<viewer::ViewerFeed> feed;
    std::unique_ptr<viewer::ViewerServer> web;
    if (!replay.empty()) {
      server.run_dir = replay;
      const fs::path scene = server.run_dir / "scene.json";
      if (!fs::is_regular_file(scene)) {
        throw ConfigError(scene.string() + ": missing (not a run directory written by the "
                          "recorder of this version?)");
      }
      web = std::make_unique<viewer::ViewerServer>(server, read_whole(scene), nullptr, nullptr);
    } else {
      const auto s = service::load_scenario(common);
      auto options = service::dds_options(common, s);
      options.identity = "viewer";  // make_security.sh --observer viewer
      web = std::make_unique<viewer::ViewerServer>(server, viewer::scene_json(s).dump(), &live,
                                                   &sensors);
      feed = std::make_unique<viewer::ViewerFeed>(options, s, live, sensors);
    }
    spdlog::info("viewer: {} at {}", replay.empty() ? "live run" : "replay of " + replay,
                 web->url());
    if (!url_file.empty()) {
      std::ofstream(url_file) << web->url() << "\n";
    }
    std::optional<std::chrono::steady_clock::time_point> ended;
    while (!service::interrupted()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (feed && exit_after_run_s >= 0 && live.ended()) {
        if (!ended) ended = std::chrono::steady_clock::now();
        if (std::chrono::steady_clock::now() - *ended >
            std::chrono::duration<double>(exit_after_run_s)) {
          break;
        }
      }
    }
    web.reset();
    feed.reset();
    return 0;
  });
}
