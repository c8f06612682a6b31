#pragma once
// The viewer's web side (docs/viewer.md): an HTTP server (civetweb) that serves the page, the
// three.js modules it imports, the scene document, a recorded run's files (replay) and, for a
// live run, a WebSocket stream of LiveState updates. Every connection has its own sender
// thread that sends the newest state whenever its browser has taken the previous update, so a
// slow or dead browser only ever slows itself. No DDS here: services/viewer/viewer_feed.hpp
// feeds the LiveState and the sensor store.
//
// Who may connect (docs/viewer.md, "Who may connect"): a request is answered only when its Host
// names this server (AccessList), and a request with an Origin header only when that origin is
// one of its pages' or one the user allowed: a page of another site open in the same browser
// can neither open /live nor read any file (DNS rebinding, cross-site WebSocket hijacking). No
// response carries CORS headers.
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

/// The listening address as the server uses it: `host` for URLs and Host headers (IPv6 in
/// brackets), whether it is IPv6 and whether it is a wildcard (every interface).
struct BindAddress {
  std::string host;
  bool ipv6 = false;
  bool wildcard = false;
};
/// `bind`: the --bind value (an IPv4 address, an IPv6 address with or without brackets, or a
/// host name). Throws ConfigError naming --bind when it is malformed, or IPv6 while the civetweb
/// library was built without IPv6.
BindAddress parse_bind(const std::string& bind);
/// Whether the civetweb library in use was built with IPv6 (mg_check_feature(8)).
bool civetweb_has_ipv6();

/// The Host headers and Origins the server answers. Hosts: the listening address (for a wildcard
/// address, 0.0.0.0 or ::, every address of this machine's interfaces and its host name),
/// localhost, 127.0.0.1 and [::1], each at the port listened on, and the extra ones given. A
/// Host header matches an allowed host when its name is the same (case-insensitive, IPv6 in
/// brackets) and its port is the allowed one or absent (clients other than browsers may leave
/// it out; a browser always names the port it connected to). Origins: http://HOST:PORT of every
/// allowed host, and the extra origins given (scheme://host[:port], exactly).
class AccessList {
 public:
  /// `hosts`: --allow-host values (NAME or NAME:PORT, NAME a host name, an IPv4 address or an
  /// IPv6 address in brackets; no port: the port listened on); `origins`: --allow-origin values
  /// (http:// or https:// URL without a path). Throws ConfigError naming the option for a
  /// malformed value.
  AccessList(const BindAddress& bind, const std::vector<std::string>& hosts,
             const std::vector<std::string>& origins);
  /// `host`: a request's Host header; `port`: the port the request arrived on.
  bool host_allowed(const std::string& host, int port) const;
  /// `origin`: a request's Origin header ("null" and schemes other than http and https are
  /// never allowed); `port`: the port the request arrived on.
  bool origin_allowed(const std::string& origin, int port) const;
  /// Every allowed host as name:port and every extra origin, `port` the port listened on.
  std::vector<std::string> describe(int port) const;

 private:
  struct Host {
    std::string name;  // lower case, IPv6 in brackets
    int port = 0;      // 0: the port listened on
  };
  struct Origin {
    std::string scheme, name;
    int port = 0;
  };
  std::vector<Host> hosts_;
  std::vector<Origin> origins_;
};

struct ServerOptions {
  std::string bind = "127.0.0.1";  // the address to listen on (0.0.0.0: every interface; IPv6
                                   // as ::1 or [::1], with a civetweb built with IPv6)
  int port = 8080;                 // 0: any free port (port() tells which)
  std::vector<std::string> allow_hosts;    // AccessList's extra hosts (--allow-host)
  std::vector<std::string> allow_origins;  // AccessList's extra origins (--allow-origin)
  std::filesystem::path web_root;  // index.html, viewer.js, style.css
  std::filesystem::path three_dir; // the three package (node_modules/three)
  std::filesystem::path run_dir;   // replay: the recorded run; empty: live only
  std::filesystem::path mesh_dir;  // OBJ meshes shared with the sensors (empty: none)
  double update_hz = 20.0;         // live updates per connection, at most
  std::size_t max_vertices_per_update = 50000;
  // Connections. Every open connection holds one of `threads` workers: a live page for as long
  // as it is open, any other until it has been answered. At most `max_live` live pages at once
  // (more are refused with 503), so at least threads - max_live workers answer requests. A
  // connection that has not sent its request within `request_timeout_ms`, or whose peer takes
  // nothing of a response for as long, is closed; a live page that answers no WebSocket ping
  // for about 6 pings (one every `request_timeout_ms` without a message from it) too.
  int threads = 24;
  int max_live = 8;
  int request_timeout_ms = 10000;
};

class ViewerServer {
 public:
  /// `scene` is the scene document; `live` and `sensors` are null for a replay.
  ViewerServer(ServerOptions options, std::string scene, LiveState* live, SensorStore* sensors);
  ~ViewerServer();
  ViewerServer(const ViewerServer&) = delete;
  ViewerServer& operator=(const ViewerServer&) = delete;

  int port() const { return port_; }
  /// The page's URL (a wildcard address as its loopback: 127.0.0.1 or [::1]).
  std::string url() const;
  /// Live connections open now.
  std::size_t connections() const;

 private:
  struct Client;
  static int begin_request(mg_connection* conn);
  static void connection_close(const mg_connection* conn);
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
  BindAddress bind_;
  AccessList access_;
  std::string scene_;
  LiveState* live_;
  SensorStore* sensors_;
  mg_context* ctx_ = nullptr;
  int port_ = 0;
  std::atomic<int> live_slots_{0};         // live pages accepted and not yet closed (<= max_live)
  std::atomic<std::uint64_t> refused_{0};  // requests refused by the access list, for the log
  mutable std::mutex clients_mutex_;
  std::map<const mg_connection*, std::unique_ptr<Client>> clients_;
};

/// `candidate` resolved inside `root`, or empty when it is outside (.., links), missing or not
/// a regular file.
std::filesystem::path file_inside(const std::filesystem::path& root, const std::string& relative);

}  // namespace syndds::viewer
