#include "viewer/viewer_server.hpp"

#include <civetweb.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <cstring>
#include <nlohmann/json.hpp>

#include "core/error.hpp"

namespace syndds::viewer {
namespace fs = std::filesystem;

void SensorStore::set_image(const std::string& vehicle, Image image) {
  std::lock_guard lock(mutex_);
  image.change = ++changes_;
  images_[vehicle] = std::move(image);
}

void SensorStore::set_points(const std::string& vehicle, Points points) {
  std::lock_guard lock(mutex_);
  points.change = ++changes_;
  points_[vehicle] = std::move(points);
}

bool SensorStore::image(const std::string& vehicle, std::uint64_t after, Image& out) const {
  std::lock_guard lock(mutex_);
  const auto it = images_.find(vehicle);
  if (it == images_.end() || it->second.change <= after) return false;
  out = it->second;
  return true;
}

bool SensorStore::points(const std::string& vehicle, std::uint64_t after, Points& out) const {
  std::lock_guard lock(mutex_);
  const auto it = points_.find(vehicle);
  if (it == points_.end() || it->second.change <= after) return false;
  out = it->second;
  return true;
}

fs::path file_inside(const fs::path& root, const std::string& relative) {
  if (relative.empty() || relative.find('\0') != std::string::npos) return {};
  std::error_code ec;
  const fs::path base = fs::weakly_canonical(root, ec);
  if (ec) return {};
  const fs::path full = fs::weakly_canonical(base / fs::path(relative).relative_path(), ec);
  if (ec) return {};
  // Inside the root: the root is a prefix of the resolved path, element by element.
  auto b = base.begin(), f = full.begin();
  for (; b != base.end(); ++b, ++f) {
    if (f == full.end() || *b != *f) return {};
  }
  if (!fs::is_regular_file(full, ec)) return {};
  return full;
}

namespace {

const char* mime_of(const fs::path& p) {
  const std::string ext = p.extension().string();
  if (ext == ".js" || ext == ".mjs") return "text/javascript";
  if (ext == ".json") return "application/json";
  if (ext == ".csv" || ext == ".txt" || ext == ".obj" || ext == ".mtl") return "text/plain; charset=utf-8";
  if (ext == ".png") return "image/png";
  if (ext == ".jpg") return "image/jpeg";
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".css") return "text/css";
  return "application/octet-stream";
}

void send_text(mg_connection* conn, int status, const char* mime, const std::string& body) {
  mg_printf(conn,
            "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\n"
            "Cache-Control: no-store\r\nConnection: close\r\n\r\n",
            status, status == 200 ? "OK" : "Not Found", mime, body.size());
  mg_write(conn, body.data(), body.size());
}

int send_file(mg_connection* conn, const fs::path& file) {
  if (file.empty()) {
    send_text(conn, 404, "text/plain", "not found\n");
    return 404;
  }
  mg_send_mime_file(conn, file.c_str(), mime_of(file));
  return 200;
}

// The part of the request's path after `prefix` ("/run/vehicles.csv" -> "vehicles.csv").
std::string after_prefix(mg_connection* conn, const char* prefix) {
  const mg_request_info* info = mg_get_request_info(conn);
  std::string uri = info->local_uri ? info->local_uri : "";
  const std::size_t n = std::strlen(prefix);
  return uri.size() > n ? uri.substr(n) : std::string();
}

bool is_mesh_file(const fs::path& p) {
  return p.extension() == ".obj" || p.extension() == ".mtl";
}

// The page's own files: its HTML, scripts and style (not package.json, not node_modules).
bool is_page_file(const fs::path& p) {
  return p.extension() == ".html" || p.extension() == ".js" || p.extension() == ".css";
}

}  // namespace

struct ViewerServer::Client {
  mg_connection* conn = nullptr;
  std::thread thread;
  std::mutex mutex;
  std::condition_variable cv;
  bool closing = false;
  std::string selected;  // the vehicle whose sensors the page shows
  std::string peer;      // "address:port", for the log
};

ViewerServer::ViewerServer(ServerOptions options, std::string scene, LiveState* live,
                           SensorStore* sensors)
    : options_(std::move(options)), scene_(std::move(scene)), live_(live), sensors_(sensors) {
  if (!fs::is_regular_file(options_.web_root / "index.html")) {
    throw ConfigError(options_.web_root.string() +
                      ": not the viewer's web folder (no index.html); pass --web-root");
  }
  if (!fs::is_regular_file(options_.three_dir / "build" / "three.module.js")) {
    throw ConfigError(options_.three_dir.string() +
                      ": three.js not found (build/three.module.js); run launch_scripts/setup.sh "
                      "(npm ci in services/viewer/web) or pass --three-dir");
  }
  mg_init_library(0);
  const std::string ports = options_.bind + ":" + std::to_string(options_.port);
  // No document_root: every file is served by a handler that knows what it may serve.
  const char* opts[] = {"listening_ports",      ports.c_str(), "num_threads", "16",
                        "websocket_timeout_ms", "3600000",     nullptr};
  mg_callbacks callbacks{};
  ctx_ = mg_start(&callbacks, this, opts);
  if (!ctx_) {
    mg_exit_library();
    throw ConfigError("viewer: cannot listen on " + ports + " (address in use or not local?)");
  }
  // Most specific first: civetweb takes the first handler whose prefix matches.
  mg_set_request_handler(ctx_, "/api/", &ViewerServer::handle_api, this);
  mg_set_request_handler(ctx_, "/run/", &ViewerServer::handle_run_file, this);
  mg_set_request_handler(ctx_, "/vendor/three/", &ViewerServer::handle_three, this);
  mg_set_request_handler(ctx_, "/meshes/", &ViewerServer::handle_mesh, this);
  mg_set_request_handler(ctx_, "/", &ViewerServer::handle_page, this);
  if (live_) {
    mg_set_websocket_handler(ctx_, "/live", &ViewerServer::ws_connect, &ViewerServer::ws_ready,
                             &ViewerServer::ws_data, &ViewerServer::ws_close, this);
  }
  mg_server_port p[4] = {};
  const int n = mg_get_server_ports(ctx_, 4, p);
  port_ = n > 0 ? p[0].port : options_.port;
}

ViewerServer::~ViewerServer() {
  {
    std::lock_guard lock(clients_mutex_);
    for (auto& [conn, c] : clients_) {
      std::lock_guard cl(c->mutex);
      c->closing = true;
      c->cv.notify_all();
    }
  }
  mg_stop(ctx_);  // closes the connections (ws_close joins their threads)
  mg_exit_library();
}

std::string ViewerServer::url() const {
  const std::string host = options_.bind == "0.0.0.0" ? "127.0.0.1" : options_.bind;
  return "http://" + host + ":" + std::to_string(port_) + "/";
}

std::size_t ViewerServer::connections() const {
  std::lock_guard lock(clients_mutex_);
  return clients_.size();
}

int ViewerServer::handle_page(mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  const std::string rel = after_prefix(conn, "/");
  const std::string name = rel.empty() ? "index.html" : rel;
  // Directly in the web root, nothing below it (node_modules is not the page's).
  if (name.find('/') != std::string::npos || !is_page_file(name)) return send_file(conn, {});
  return send_file(conn, file_inside(self->options_.web_root, name));
}

int ViewerServer::handle_api(mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  const std::string what = after_prefix(conn, "/api/");
  if (what == "scene") {
    send_text(conn, 200, "application/json", self->scene_);
    return 200;
  }
  if (what == "info") {
    nlohmann::json info = {{"mode", self->live_ ? "live" : "replay"}};
    if (!self->options_.run_dir.empty()) {
      nlohmann::json files = nlohmann::json::array();
      std::error_code ec;
      for (const auto& e : fs::directory_iterator(self->options_.run_dir, ec)) {
        if (e.is_regular_file()) files.push_back(e.path().filename().string());
      }
      std::sort(files.begin(), files.end());
      info["run_files"] = files;
    }
    info["meshes"] = self->mesh_names();
    send_text(conn, 200, "application/json", info.dump());
    return 200;
  }
  send_text(conn, 404, "text/plain", "unknown api '" + what + "'\n");
  return 404;
}

int ViewerServer::handle_run_file(mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  if (self->options_.run_dir.empty()) return send_file(conn, {});
  return send_file(conn, file_inside(self->options_.run_dir, after_prefix(conn, "/run/")));
}

int ViewerServer::handle_three(mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  const std::string rel = after_prefix(conn, "/vendor/three/");
  // The module and its add-ons (the modules the page imports, index.html's import map) only.
  const bool module = rel.rfind("build/", 0) == 0 || rel.rfind("examples/jsm/", 0) == 0;
  if (!module || fs::path(rel).extension() != ".js") return send_file(conn, {});
  return send_file(conn, file_inside(self->options_.three_dir, rel));
}

std::vector<std::string> ViewerServer::mesh_names() const {
  std::vector<std::string> names;
  if (options_.mesh_dir.empty()) return names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(options_.mesh_dir, ec)) {
    if (e.is_regular_file() && !e.is_symlink() && e.path().extension() == ".obj") {
      names.push_back(e.path().stem().string());
    }
  }
  std::sort(names.begin(), names.end());
  return names;
}

int ViewerServer::handle_mesh(mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  const std::string rel = after_prefix(conn, "/meshes/");
  // Meshes and their materials only, directly in the folder.
  if (self->options_.mesh_dir.empty() || rel.find('/') != std::string::npos ||
      !is_mesh_file(rel)) {
    return send_file(conn, {});
  }
  return send_file(conn, file_inside(self->options_.mesh_dir, rel));
}

int ViewerServer::ws_connect(const mg_connection*, void*) { return 0; }  // 0: accept

void ViewerServer::ws_ready(mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  auto client = std::make_unique<Client>();
  client->conn = conn;
  const mg_request_info* info = mg_get_request_info(conn);
  client->peer = std::string(info->remote_addr) + ":" + std::to_string(info->remote_port);
  spdlog::info("viewer: browser at {} connected", client->peer);
  Client& c = *client;
  {
    std::lock_guard lock(self->clients_mutex_);
    self->clients_[conn] = std::move(client);
  }
  c.thread = std::thread([self, &c] { self->send_loop(c); });
}

int ViewerServer::ws_data(mg_connection* conn, int bits, char* data, std::size_t len,
                          void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  if ((bits & 0x0f) == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE) return 0;
  if ((bits & 0x0f) != MG_WEBSOCKET_OPCODE_TEXT) return 1;
  // {"select": "VEHICLE"}: the vehicle whose camera image and lidar points to send.
  const auto msg = nlohmann::json::parse(std::string(data, len), nullptr, false);
  if (msg.is_object() && msg.contains("select") && msg["select"].is_string()) {
    std::lock_guard lock(self->clients_mutex_);
    const auto it = self->clients_.find(conn);
    if (it != self->clients_.end()) {
      std::lock_guard cl(it->second->mutex);
      it->second->selected = msg["select"].get<std::string>();
    }
  }
  return 1;
}

void ViewerServer::ws_close(const mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  std::unique_ptr<Client> client;
  {
    std::lock_guard lock(self->clients_mutex_);
    const auto it = self->clients_.find(conn);
    if (it == self->clients_.end()) return;
    client = std::move(it->second);
    self->clients_.erase(it);
  }
  {
    std::lock_guard cl(client->mutex);
    client->closing = true;
  }
  client->cv.notify_all();
  if (client->thread.joinable()) client->thread.join();
  spdlog::info("viewer: browser at {} disconnected", client->peer);
}

void ViewerServer::send_loop(Client& c) {
  Cursor cursor;
  std::uint64_t image_seen = 0, points_seen = 0;
  std::string image_vehicle;
  const auto period = std::chrono::duration<double>(1.0 / options_.update_hz);
  const auto write = [&](int opcode, const std::string& data) {
    const int n = mg_websocket_write(c.conn, opcode, data.data(), data.size());
    // A browser that went away (closed, killed): its connection closes next.
    if (n <= 0) spdlog::info("viewer: writing to the browser at {} failed: no more updates", c.peer);
    return n > 0;
  };
  const auto write_text = [&](const std::string& text) {
    return write(MG_WEBSOCKET_OPCODE_TEXT, text);
  };
  nlohmann::json hello = {{"type", "scene"}, {"scene", nlohmann::json::parse(scene_)}};
  if (!write_text(hello.dump())) return;
  for (;;) {
    std::string selected;
    {
      std::unique_lock lock(c.mutex);
      if (c.closing) return;
      selected = c.selected;
    }
    bool more = false;
    // Blocks while the browser has not taken the previous update: the next one is newer.
    // Nothing new, nothing sent (a browser redraws on every update).
    if (live_->has_news(cursor) &&
        !write_text(live_->update(cursor, options_.max_vertices_per_update, &more))) {
      return;
    }
    if (sensors_ && !selected.empty()) {
      if (selected != image_vehicle) image_seen = points_seen = 0, image_vehicle = selected;
      SensorStore::Image image;
      if (sensors_->image(selected, image_seen, image)) {
        image_seen = image.change;
        if (!write(MG_WEBSOCKET_OPCODE_BINARY, image.jpeg)) return;
      }
      SensorStore::Points points;
      if (sensors_->points(selected, points_seen, points)) {
        points_seen = points.change;
        nlohmann::json p = {{"type", "points"}, {"vehicle", selected}, {"sensor", points.sensor},
                            {"frame", points.frame}, {"xyz", points.xyz}};
        if (!write_text(p.dump())) return;
      }
    }
    if (more) continue;  // soil changes left: send them at once
    std::unique_lock lock(c.mutex);
    c.cv.wait_for(lock, period, [&] { return c.closing; });
  }
}

}  // namespace syndds::viewer
