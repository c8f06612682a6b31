#include "viewer/live_state.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

namespace syndds::viewer {
namespace {

// The real-time factor is measured over the grants seen in the last few seconds of wall time
// (a count of frames would shrink to a burst of late deliveries after a stall).
constexpr double kRateWindowS = 3.0;

std::uint64_t vertex_key(std::int32_t i, std::int32_t j) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(i)) << 32) |
         static_cast<std::uint32_t>(j);
}

nlohmann::json pose_json(const Pose& p) {
  return {p.position.x(),    p.position.y(),    p.position.z(),   p.orientation.w(),
          p.orientation.x(), p.orientation.y(), p.orientation.z()};
}

}  // namespace

void LiveState::on_vehicle_state(const proto::VehicleStateMsg& s) {
  std::lock_guard lock(mutex_);
  Vehicle& v = vehicles_[s.vehicle_id];
  if (v.change != 0 && s.frame < v.state.frame) return;
  v.state = s;
  v.change = ++vehicle_changes_;
}

void LiveState::on_collision(const proto::CollisionEventMsg& e) {
  std::lock_guard lock(mutex_);
  contacts_.push_back({++contact_changes_, e});
  if (contacts_.size() > kMaxContactMarks) contacts_.pop_front();
}

void LiveState::on_radar(const proto::RadarScanMsg& m) {
  std::lock_guard lock(mutex_);
  const auto key = std::make_pair(m.vehicle_id, m.stamp.sensor_id);
  auto it = radar_.find(key);
  if (it == radar_.end()) {
    if (radar_.size() >= kMaxRadarSensors) return;
    it = radar_.emplace(key, RadarScan{}).first;
  } else if (m.stamp.time_s < it->second.time_s) {
    return;
  }
  RadarScan& s = it->second;
  s.frame = m.frame;
  s.time_s = m.stamp.time_s;
  s.detections.clear();
  const Eigen::Matrix3d r = m.pose.orientation.toRotationMatrix();
  for (const auto& d : m.detections) {
    if (s.detections.size() >= kMaxRadarDetections) break;
    const Vec3 at = m.pose.position + r * Vec3(d.x, d.y, d.z);
    if (!at.allFinite()) continue;
    s.detections.push_back({at, d.radial_speed_mps, d.strength_db});
  }
  s.change = ++radar_changes_;
}

void LiveState::on_terrain(const std::vector<proto::TerrainVertexMsg>& vertices) {
  std::lock_guard lock(mutex_);
  for (const auto& x : vertices) {
    const std::uint64_t key = vertex_key(x.i, x.j);
    Vertex& v = soil_[key];
    v.i = x.i;
    v.j = x.j;
    v.height = x.height;
    v.change = ++soil_changes_;
    soil_log_.emplace_back(v.change, key);
  }
  if (soil_log_.size() > 2 * soil_.size() + 4096) compact_soil();
}

void LiveState::compact_soil() {
  // Keep only each vertex's newest change, in change order: a cursor anywhere in the old log
  // still gets every vertex whose newest change it has not seen.
  std::vector<std::pair<std::uint64_t, std::uint64_t>> kept;
  kept.reserve(soil_.size());
  for (const auto& [change, key] : soil_log_) {
    if (soil_.at(key).change == change) kept.emplace_back(change, key);
  }
  soil_log_ = std::move(kept);
}

void LiveState::on_frame(std::int64_t frame, double sim_time_s, double wall_s) {
  std::lock_guard lock(mutex_);
  if (frame <= frame_) return;
  frame_ = frame;
  sim_time_s_ = sim_time_s;
  recent_.emplace_back(wall_s, sim_time_s);
  while (recent_.size() > 2 && recent_.front().first < wall_s - kRateWindowS) {
    recent_.pop_front();
  }
}

void LiveState::on_member(const proto::MemberAnnounceMsg& m, double) {
  std::lock_guard lock(mutex_);
  Member next{std::string(proto::to_string(m.kind)), m.host, m.pid};
  auto it = members_.find(m.member_id);
  if (it != members_.end() && it->second.kind == next.kind && it->second.host == next.host &&
      it->second.pid == next.pid) {
    return;
  }
  members_[m.member_id] = std::move(next);
  ++member_changes_;
}

void LiveState::on_run_end(const proto::RunControlMsg& c) {
  std::lock_guard lock(mutex_);
  status_ = std::string(proto::to_string(c.status));
  reason_ = c.reason;
  ++status_changes_;
}

bool LiveState::has_news(const Cursor& cursor) const {
  std::lock_guard lock(mutex_);
  return cursor.frame != frame_ || cursor.vehicles < vehicle_changes_ ||
         cursor.terrain < soil_changes_ || cursor.members < member_changes_ ||
         cursor.status < status_changes_ || cursor.contacts < contact_changes_ ||
         cursor.radar < radar_changes_;
}

std::string LiveState::update(Cursor& cursor, std::size_t max_vertices, bool* more) {
  std::lock_guard lock(mutex_);
  nlohmann::json u = {{"type", "update"}, {"frame", frame_}, {"sim_time_s", sim_time_s_}};
  if (recent_.size() >= 2 && recent_.back().second > recent_.front().second) {
    u["real_time_factor"] = (recent_.back().first - recent_.front().first) /
                            (recent_.back().second - recent_.front().second);
  } else {
    u["real_time_factor"] = nullptr;
  }
  nlohmann::json vehicles = nlohmann::json::array();
  for (const auto& [id, v] : vehicles_) {
    if (v.change <= cursor.vehicles) continue;
    const auto& s = v.state;
    nlohmann::json wheels = nlohmann::json::array();
    for (const auto& w : s.wheels) {
      auto pose = pose_json(w.pose);
      pose.push_back(w.spin_rad_s);
      wheels.push_back(pose);
    }
    vehicles.push_back({{"id", id},
                        {"frame", s.frame},
                        {"time_s", s.sim_time_s},
                        {"pose", pose_json(s.pose)},
                        {"wheels", wheels},
                        {"speed_mps", s.linear_velocity.norm()},
                        {"steering", s.steering},
                        {"throttle", s.throttle},
                        {"braking", s.braking},
                        {"gear", s.gear},
                        {"engine_speed_rpm", s.engine_speed_rpm}});
  }
  cursor.vehicles = vehicle_changes_;
  u["vehicles"] = vehicles;
  nlohmann::json contacts = nlohmann::json::array();
  for (const auto& c : contacts_) {
    if (c.number <= cursor.contacts) continue;
    const auto& e = c.event;
    contacts.push_back({{"frame", e.frame},
                        {"vehicle", e.vehicle_id},
                        {"with", e.other_vehicle_id.empty() ? e.obstacle_id : e.other_vehicle_id},
                        {"vehicle_contact", !e.other_vehicle_id.empty()},
                        {"at", {e.position.x(), e.position.y(), e.position.z()}}});
  }
  cursor.contacts = contact_changes_;
  u["contacts"] = contacts;
  nlohmann::json radar = nlohmann::json::array();
  for (const auto& [key, s] : radar_) {
    if (s.change <= cursor.radar) continue;
    nlohmann::json detections = nlohmann::json::array();
    for (const auto& d : s.detections) {
      detections.push_back({{"at", {d.at.x(), d.at.y(), d.at.z()}},
                            {"radial_speed_mps", d.radial_speed_mps},
                            {"strength_db", d.strength_db}});
    }
    radar.push_back({{"vehicle", key.first},
                     {"sensor", key.second},
                     {"frame", s.frame},
                     {"time_s", s.time_s},
                     {"detections", detections}});
  }
  cursor.radar = radar_changes_;
  u["radar"] = radar;
  // Soil: the log is in change order; start after the cursor.
  auto it = std::upper_bound(soil_log_.begin(), soil_log_.end(),
                             std::make_pair(cursor.terrain, ~std::uint64_t{0}));
  nlohmann::json soil = nlohmann::json::array();
  std::size_t sent = 0;
  for (; it != soil_log_.end() && sent < max_vertices; ++it) {
    const Vertex& v = soil_.at(it->second);
    cursor.terrain = it->first;
    if (v.change != it->first) continue;  // a newer change of this vertex comes later
    soil.push_back({v.i, v.j, v.height});
    ++sent;
  }
  if (it == soil_log_.end()) cursor.terrain = soil_changes_;
  if (more) *more = it != soil_log_.end();
  u["soil"] = soil;
  if (cursor.members < member_changes_) {
    nlohmann::json members = nlohmann::json::array();
    for (const auto& [id, m] : members_) {
      members.push_back({{"id", id}, {"kind", m.kind}, {"host", m.host}, {"pid", m.pid}});
    }
    u["members"] = members;
    cursor.members = member_changes_;
  }
  u["status"] = status_;
  if (!reason_.empty()) u["reason"] = reason_;
  cursor.status = status_changes_;
  cursor.frame = frame_;
  return u.dump();
}

std::int64_t LiveState::frame() const {
  std::lock_guard lock(mutex_);
  return frame_;
}

bool LiveState::ended() const {
  std::lock_guard lock(mutex_);
  return status_ != "running";
}

std::size_t LiveState::soil_vertices() const {
  std::lock_guard lock(mutex_);
  return soil_.size();
}

std::size_t LiveState::soil_log_size() const {
  std::lock_guard lock(mutex_);
  return soil_log_.size();
}

std::size_t LiveState::radar_scans() const {
  std::lock_guard lock(mutex_);
  return radar_.size();
}

}  // namespace syndds::viewer
