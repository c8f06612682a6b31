#pragma once
// The viewer's web side (docs/viewer.md): an HTTP server (civetweb) that serves the page, the
// three.js modules it imports, the scene document, a recorded run's files (replay) and, for a
// live run, a WebSocket stream of LiveState updates. Every connection has its own sender
// thread that sends the newest state whenever its browser has taken the previous update, so a
// slow or dead browser only ever slows itself. No DDS here: services/viewer/viewer_feed.hpp
// feeds the LiveState and the sensor store.
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "viewer/live_state.hpp"

struct mg_context;
struct mg_connection;

namespace syndds::viewer {

/// The newest camera image (JPEG) and lidar points (world frame) of each vehicle.
class SensorStore {
 public:
  struct Image {
    std::string sensor;
    std::int64_t frame = 0;
    std::string jpeg;
    std::uint64_t change = 0;
  };
  struct Points {
    std::string sensor;
    std::int64_t frame = 0;
    std::vector<float> xyz;  // world frame, x y z per point
    std::uint64_t change = 0;
  };
  void set_image(const std::string& vehicle, Image image);
  void set_points(const std::string& vehicle, Points points);
  /// Copies of the newest entries newer than `after` (nothing when none is newer).
  bool image(const std::string& vehicle, std::uint64_t after, Image& out) const;
  bool points(const std::string& vehicle, std::uint64_t after, Points& out) const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, Image> images_;
  std::map<std::string, Points> points_;
  std::uint64_t changes_ = 0;
};

struct ServerOptions {
  std::string bind = "127.0.0.1";  // the address to listen on (0.0.0.0: every interface)
  int port = 8080;                 // 0: any free port (port() tells which)
  std::filesystem::path web_root;  // index.html, viewer.js, style.css
  std::filesystem::path three_dir; // the three package (node_modules/three)
  std::filesystem::path run_dir;   // replay: the recorded run; empty: live only
  std::filesystem::path mesh_dir;  // OBJ meshes shared with the sensors (empty: none)
  double update_hz = 20.0;         // live updates per connection, at most
  std::size_t max_vertices_per_update = 50000;
};

class ViewerServer {
 public:
  /// `scene` is the scene document; `live` and `sensors` are null for a replay.
  ViewerServer(ServerOptions options, std::string scene, LiveState* live, SensorStore* sensors);
  ~ViewerServer();
  ViewerServer(const ViewerServer&) = delete;
  ViewerServer& operator=(const ViewerServer&) = delete;

  int port() const { return port_; }
  std::string url() const;
  /// Live connections open now.
  std::size_t connections() const;

 private:
  struct Client;
  static int handle_page(mg_connection* conn, void* self);
  static int handle_api(mg_connection* conn, void* self);
  static int handle_run_file(mg_connection* conn, void* self);
  static int handle_three(mg_connection* conn, void* self);
  static int handle_mesh(mg_connection* conn, void* self);
  std::vector<std::string> mesh_names() const;  // the .obj files of mesh_dir, without extension
  static int ws_connect(const mg_connection* conn, void* self);
  static void ws_ready(mg_connection* conn, void* self);
  static int ws_data(mg_connection* conn, int bits, char* data, std::size_t len, void* self);
  static void ws_close(const mg_connection* conn, void* self);
  void send_loop(Client& client);

  ServerOptions options_;
  std::string scene_;
  LiveState* live_;
  SensorStore* sensors_;
  mg_context* ctx_ = nullptr;
  int port_ = 0;
  mutable std::mutex clients_mutex_;
  std::map<const mg_connection*, std::unique_ptr<Client>> clients_;
};

/// `candidate` resolved inside `root`, or empty when it is outside (.., links), missing or not
/// a regular file.
std::filesystem::path file_inside(const std::filesystem::path& root, const std::string& relative);

}  // namespace syndds::viewer
