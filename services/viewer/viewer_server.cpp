#include "viewer/viewer_server.hpp"

#include <arpa/inet.h>
#include <civetweb.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <nlohmann/json.hpp>
#include <optional>
#include <string_view>

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

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// An IPv6 address in its canonical text ("::1"), or nullopt when `text` is not one.
std::optional<std::string> canonical_ipv6(const std::string& text) {
  in6_addr a{};
  if (inet_pton(AF_INET6, text.c_str(), &a) != 1) return std::nullopt;
  char buf[INET6_ADDRSTRLEN] = {};
  inet_ntop(AF_INET6, &a, buf, sizeof buf);
  return std::string(buf);
}

bool is_host_name(std::string_view s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-' || c == '_';
  });
}

struct HostPort {
  std::string name;  // lower case, IPv6 canonical in brackets
  int port = 0;      // 0: none given
};

// "NAME", "NAME:PORT", "[IPV6]" or "[IPV6]:PORT"; nullopt when malformed.
std::optional<HostPort> split_host(std::string_view s) {
  HostPort h;
  std::string_view rest;
  if (!s.empty() && s.front() == '[') {
    const std::size_t close = s.find(']');
    if (close == std::string_view::npos) return std::nullopt;
    const auto v6 = canonical_ipv6(std::string(s.substr(1, close - 1)));
    if (!v6) return std::nullopt;
    h.name = "[" + *v6 + "]";
    rest = s.substr(close + 1);
  } else {
    const std::size_t colon = s.find(':');
    h.name = lower(s.substr(0, colon));
    if (!is_host_name(h.name)) return std::nullopt;
    if (colon != std::string_view::npos) rest = s.substr(colon);
  }
  if (rest.empty()) return h;
  if (rest.front() != ':' || rest.size() < 2 || rest.size() > 6) return std::nullopt;
  int port = 0;
  for (const char c : rest.substr(1)) {
    if (!std::isdigit(static_cast<unsigned char>(c))) return std::nullopt;
    port = port * 10 + (c - '0');
  }
  if (port < 1 || port > 65535) return std::nullopt;
  h.port = port;
  return h;
}

struct OriginParts {
  std::string scheme, name;
  int port = 0;  // the scheme's default when the origin names none
};

// "http://HOST[:PORT]" or "https://HOST[:PORT]" (with `slash`: a final "/" too).
std::optional<OriginParts> split_origin(std::string_view s, bool slash) {
  const std::size_t sep = s.find("://");
  if (sep == std::string_view::npos) return std::nullopt;
  OriginParts o;
  o.scheme = lower(s.substr(0, sep));
  if (o.scheme != "http" && o.scheme != "https") return std::nullopt;
  std::string_view rest = s.substr(sep + 3);
  if (slash && !rest.empty() && rest.back() == '/') rest.remove_suffix(1);
  const auto h = split_host(rest);
  if (!h) return std::nullopt;
  o.name = h->name;
  o.port = h->port ? h->port : (o.scheme == "https" ? 443 : 80);
  return o;
}

// This machine's interface addresses (IPv6 in brackets) and host name.
std::vector<std::string> machine_names() {
  std::vector<std::string> names;
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) == 0) {
    for (const ifaddrs* a = list; a; a = a->ifa_next) {
      if (!a->ifa_addr) continue;
      char buf[INET6_ADDRSTRLEN] = {};
      if (a->ifa_addr->sa_family == AF_INET) {
        inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(a->ifa_addr)->sin_addr, buf,
                  sizeof buf);
        names.emplace_back(buf);
      } else if (a->ifa_addr->sa_family == AF_INET6) {
        inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(a->ifa_addr)->sin6_addr, buf,
                  sizeof buf);
        names.push_back("[" + std::string(buf) + "]");
      }
    }
    freeifaddrs(list);
  }
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) == 0 && is_host_name(host)) names.push_back(lower(host));
  return names;
}

}  // namespace

bool civetweb_has_ipv6() { return mg_check_feature(8) != 0; }

BindAddress parse_bind(const std::string& bind) {
  std::string text = bind;
  const bool bracketed = text.size() >= 2 && text.front() == '[' && text.back() == ']';
  if (bracketed) text = text.substr(1, text.size() - 2);
  if (const auto v6 = canonical_ipv6(text)) {
    if (!civetweb_has_ipv6()) {
      throw ConfigError("--bind " + bind +
                        ": an IPv6 address, but the civetweb library this viewer uses was built "
                        "without IPv6; bind an IPv4 address (127.0.0.1, or 0.0.0.0 for every "
                        "interface)");
    }
    return {"[" + *v6 + "]", true, *v6 == "::"};
  }
  if (bracketed) throw ConfigError("--bind " + bind + ": not an IPv6 address in brackets");
  in_addr v4{};
  if (inet_pton(AF_INET, text.c_str(), &v4) == 1) return {text, false, v4.s_addr == INADDR_ANY};
  if (!is_host_name(text)) {
    throw ConfigError("--bind '" + bind +
                      "': expected an IPv4 address (127.0.0.1), an IPv6 address (::1 or [::1]) or "
                      "a host name");
  }
  return {lower(text), false, false};
}

AccessList::AccessList(const BindAddress& bind, const std::vector<std::string>& hosts,
                       const std::vector<std::string>& origins) {
  std::vector<std::string> names = {"localhost", "127.0.0.1", "[::1]"};
  if (bind.wildcard) {
    for (auto& n : machine_names()) names.push_back(std::move(n));
  } else {
    names.push_back(bind.host);
  }
  for (const auto& n : names) {
    if (std::none_of(hosts_.begin(), hosts_.end(), [&](const Host& h) { return h.name == n; })) {
      hosts_.push_back({n, 0});
    }
  }
  for (const auto& h : hosts) {
    const auto parts = split_host(h);
    if (!parts) {
      throw ConfigError("--allow-host '" + h +
                        "': expected NAME or NAME:PORT (a host name, an IPv4 address or an IPv6 "
                        "address in brackets, [::1])");
    }
    hosts_.push_back({parts->name, parts->port});
  }
  for (const auto& o : origins) {
    const auto parts = split_origin(o, true);
    if (!parts) {
      throw ConfigError("--allow-origin '" + o +
                        "': expected http://HOST[:PORT] or https://HOST[:PORT] (no path)");
    }
    origins_.push_back({parts->scheme, parts->name, parts->port});
  }
}

bool AccessList::host_allowed(const std::string& host, int port) const {
  const auto h = split_host(host);
  if (!h) return false;
  return std::any_of(hosts_.begin(), hosts_.end(), [&](const Host& a) {
    return a.name == h->name && (h->port == 0 || h->port == (a.port ? a.port : port));
  });
}

bool AccessList::origin_allowed(const std::string& origin, int port) const {
  const auto o = split_origin(origin, false);
  if (!o) return false;
  const bool page =
      o->scheme == "http" && std::any_of(hosts_.begin(), hosts_.end(), [&](const Host& a) {
        return a.name == o->name && o->port == (a.port ? a.port : port);
      });
  return page || std::any_of(origins_.begin(), origins_.end(), [&](const Origin& a) {
           return a.scheme == o->scheme && a.name == o->name && a.port == o->port;
         });
}

std::vector<std::string> AccessList::describe(int port) const {
  std::vector<std::string> out;
  for (const auto& h : hosts_) out.push_back(h.name + ":" + std::to_string(h.port ? h.port : port));
  for (const auto& o : origins_) {
    out.push_back(o.scheme + "://" + o.name + ":" + std::to_string(o.port));
  }
  return out;
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

const char* reason_of(int status) {
  switch (status) {
    case 200:
      return "OK";
    case 403:
      return "Forbidden";
    case 503:
      return "Service Unavailable";
    default:
      return "Not Found";
  }
}

void send_text(mg_connection* conn, int status, const char* mime, const std::string& body) {
  mg_printf(conn,
            "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\n"
            "Cache-Control: no-store\r\nConnection: close\r\n\r\n",
            status, reason_of(status), mime, body.size());
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

// A request's header as it may go into the log and an answer: printable ASCII, at most 200
// characters.
std::string printable(std::string_view s) {
  std::string out(s.substr(0, 200));
  for (char& c : out) {
    if (c < 0x20 || c > 0x7e) c = '?';
  }
  return out;
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
    : options_(std::move(options)),
      bind_(parse_bind(options_.bind)),
      access_(bind_, options_.allow_hosts, options_.allow_origins),
      scene_(std::move(scene)),
      live_(live),
      sensors_(sensors) {
  if (!fs::is_regular_file(options_.web_root / "index.html")) {
    throw ConfigError(options_.web_root.string() +
                      ": not the viewer's web folder (no index.html); pass --web-root");
  }
  if (!fs::is_regular_file(options_.three_dir / "build" / "three.module.js")) {
    throw ConfigError(options_.three_dir.string() +
                      ": three.js not found (build/three.module.js); run launch_scripts/setup.sh "
                      "(npm ci in services/viewer/web) or pass --three-dir");
  }
  if (options_.max_live < 1 || options_.threads <= options_.max_live ||
      options_.request_timeout_ms < 1) {
    throw ConfigError("viewer: expected 1 <= max_live < threads and request_timeout_ms >= 1");
  }
  mg_init_library(0);
  const std::string ports = bind_.host + ":" + std::to_string(options_.port);
  const std::string threads = std::to_string(options_.threads);
  const std::string timeout = std::to_string(options_.request_timeout_ms);
  // No document_root: every file is served by a handler that knows what it may serve. Empty
  // access_control_* values: no CORS headers, so no other site's page may read a response.
  const char* opts[] = {"listening_ports",
                        ports.c_str(),
                        "num_threads",
                        threads.c_str(),
                        "request_timeout_ms",
                        timeout.c_str(),
                        "websocket_timeout_ms",
                        timeout.c_str(),
                        "enable_websocket_ping_pong",
                        "yes",
                        "enable_keep_alive",
                        "no",
                        "access_control_allow_origin",
                        "",
                        "access_control_allow_methods",
                        "",
                        "access_control_allow_headers",
                        "",
                        nullptr};
  mg_callbacks callbacks{};
  callbacks.begin_request = &ViewerServer::begin_request;
  callbacks.connection_close = &ViewerServer::connection_close;
  ctx_ = mg_start(&callbacks, this, opts);
  if (!ctx_) {
    mg_exit_library();
    throw ConfigError("--bind " + options_.bind + " --port " + std::to_string(options_.port) +
                      ": cannot listen there (the port is in use, or the address is not one of "
                      "this machine's)");
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
  std::string hosts;
  for (const auto& h : access_.describe(port_)) hosts += (hosts.empty() ? "" : ", ") + h;
  spdlog::info("viewer: answering requests for {} (more: --allow-host, --allow-origin)", hosts);
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
  const std::string host = bind_.wildcard ? (bind_.ipv6 ? "[::1]" : "127.0.0.1") : bind_.host;
  return "http://" + host + ":" + std::to_string(port_) + "/";
}

std::size_t ViewerServer::connections() const {
  std::lock_guard lock(clients_mutex_);
  return clients_.size();
}

int ViewerServer::begin_request(mg_connection* conn) {
  const mg_request_info* info = mg_get_request_info(conn);
  auto* self = static_cast<ViewerServer*>(info->user_data);
  const char* host = mg_get_header(conn, "Host");
  const char* origin = mg_get_header(conn, "Origin");
  std::string refused;
  if (!host) {
    refused = "no Host header";
  } else if (!self->access_.host_allowed(host, info->server_port)) {
    refused = "Host '" + printable(host) + "' not allowed";
  } else if (origin && !self->access_.origin_allowed(origin, info->server_port)) {
    refused = "Origin '" + printable(origin) + "' not allowed";
  } else {
    return 0;  // civetweb goes on to the handlers
  }
  // The first refusals and then every 1000th: a page that keeps trying cannot fill the log.
  const std::uint64_t n = ++self->refused_;
  if (n <= 10 || n % 1000 == 0) {
    spdlog::warn("viewer: refused {} {} from {}: {} (--allow-host, --allow-origin; {} refused)",
                 printable(info->request_method), printable(info->local_uri ? info->local_uri : ""),
                 info->remote_addr, refused, n);
  }
  send_text(conn, 403, "text/plain", "forbidden: " + refused + "\n");
  return 403;
}

void ViewerServer::connection_close(const mg_connection* conn) {
  auto* self = static_cast<ViewerServer*>(mg_get_user_data(mg_get_context(conn)));
  // A connection ws_connect accepted carries the server as its data until civetweb closes it,
  // whether or not its handshake completed.
  if (mg_get_user_connection_data(conn) == self) --self->live_slots_;
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

int ViewerServer::ws_connect(const mg_connection* conn, void* self_ptr) {
  auto* self = static_cast<ViewerServer*>(self_ptr);
  int live = self->live_slots_.load();
  do {
    if (live >= self->options_.max_live) {
      const mg_request_info* info = mg_get_request_info(conn);
      spdlog::warn("viewer: refused a live page at {}: {} open already", info->remote_addr, live);
      // Before the handshake the connection still speaks HTTP (civetweb passes it as const).
      send_text(const_cast<mg_connection*>(conn), 503, "text/plain",
                "too many live pages open (" + std::to_string(live) + ")\n");
      return 1;  // no handshake
    }
  } while (!self->live_slots_.compare_exchange_weak(live, live + 1));
  mg_set_user_connection_data(conn, self);
  return 0;  // accept
}

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
