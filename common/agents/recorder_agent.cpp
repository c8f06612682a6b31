#include "agents/recorder_agent.hpp"

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "agents/scm_messages.hpp"
#include "core/error.hpp"
#include "scm/scm_images.hpp"

namespace syndds::record {
namespace fs = std::filesystem;
namespace {

std::FILE* open_csv(const fs::path& file, const char* header) {
  std::FILE* f = std::fopen(file.c_str(), "w");
  if (!f) throw ConfigError(file.string() + ": cannot create file");
  std::fputs(header, f);
  std::fputc('\n', f);
  return f;
}

void write_text_atomically(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.string() + ".tmp";
  {
    std::ofstream out(tmp);
    out << text;
  }
  fs::rename(tmp, file);
}

// CSV fields must not carry separators or line breaks.
std::string csv_safe(std::string s) {
  for (char& c : s) {
    if (c == ',' || c == '\n' || c == '\r') c = ';';
  }
  return s;
}

nlohmann::json stat_json(const convoy::Stat& s) {
  return {{"mean", s.mean}, {"min", s.min}, {"max", s.max}, {"samples", s.samples}};
}

nlohmann::json convoy_json(const std::vector<convoy::FollowerReport>& reports) {
  nlohmann::json out = nlohmann::json::array();
  for (const auto& r : reports) {
    out.push_back({{"follower", r.follower},
                   {"follows", r.leader},
                   {"distance_gap_m", stat_json(r.distance_gap_m)},
                   {"time_gap_s", stat_json(r.time_gap_s)},
                   {"cross_track_m", stat_json(r.cross_track_m)},
                   {"obstacles_hit", r.obstacles_hit},
                   {"leader_lost_events", r.leader_lost_events}});
  }
  return out;
}

std::string convoy_table(const std::vector<convoy::FollowerReport>& reports) {
  // Gaps in metres and seconds, cross-track in metres (definitions: docs/convoy.md).
  std::string text = fmt::format("  {:<10} {:<8} {:>20} {:>20} {:>15} {:>9} {:>11}\n", "follower",
                                 "follows", "gap m mean/min/max", "gap s mean/min/max",
                                 "cross m mean/max", "obstacles", "leader_lost");
  for (const auto& r : reports) {
    text += fmt::format("  {:<10} {:<8} {:>20} {:>20} {:>15} {:>9} {:>11}\n", r.follower, r.leader,
                        fmt::format("{:.1f}/{:.1f}/{:.1f}", r.distance_gap_m.mean,
                                    r.distance_gap_m.min, r.distance_gap_m.max),
                        fmt::format("{:.2f}/{:.2f}/{:.2f}", r.time_gap_s.mean, r.time_gap_s.min,
                                    r.time_gap_s.max),
                        fmt::format("{:.2f}/{:.2f}", r.cross_track_m.mean, r.cross_track_m.max),
                        r.obstacles_hit, r.leader_lost_events);
  }
  return text;
}

}  // namespace

RecorderAgent::RecorderAgent(const scenario::Scenario& scenario, RecorderOptions options)
    : options_(std::move(options)),
      scenario_name_(scenario.name),
      scenario_file_(scenario.file),
      heartbeat_s_(scenario.time.heartbeat_s),
      members_(scenario.member_ids()) {
  bool v2v = false;
  for (const auto& v : scenario.vehicles) {
    vehicle_ids_.push_back(v.id);
    totals_[v.id];
    v2v = v2v || v.v2v.has_value();
    if (v.controller.type == "follower") followers_.emplace_back(v.id, v.controller.convoy.leader);
  }
  if (scenario.terrain.deformable()) {
    soil_ = std::make_unique<scm::ScmTerrain>(scenario.terrain.scm);
    soil_->set_source_id(static_cast<std::uint32_t>(members_.size()));  // never wins a tie
  }
  const fs::path dir(options_.output_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw ConfigError(dir.string() + ": cannot create output directory: " + ec.message());
  vehicles_ = open_csv(dir / "vehicles.csv",
                       "frame,time_s,vehicle,x,y,z,qw,qx,qy,qz,vx,vy,vz,speed_mps,steering,"
                       "throttle,braking,gear,engine_speed_rpm");
  commands_ = open_csv(dir / "commands.csv",
                       "frame,time_s,vehicle,source,steering,throttle,braking,rejected");
  events_ = open_csv(dir / "events.csv", "frame,time_s,kind,vehicle,detail");
  bool interoceptive = false;
  for (const auto& v : scenario.vehicles) interoceptive = interoceptive || v.has_interoceptive_sensors();
  if (interoceptive) {
    const char* stamp = "frame,vehicle,sensor,sequence,time_s,available_s,";
    gps_ = open_csv(dir / "gps.csv",
                    (std::string(stamp) + "latitude_deg,longitude_deg,altitude_m,e_m,n_m,u_m").c_str());
    imu_ = open_csv(dir / "imu.csv",
                    (std::string(stamp) + "ax_mps2,ay_mps2,az_mps2,gx_rad_s,gy_rad_s,gz_rad_s").c_str());
    compass_ = open_csv(dir / "compass.csv",
                        (std::string(stamp) + "heading_rad,fx_ut,fy_ut,fz_ut").c_str());
    wheel_speeds_ = open_csv(dir / "wheel_speeds.csv",
                             (std::string(stamp) + "fl_rad_s,fr_rad_s,rl_rad_s,rr_rad_s").c_str());
  }
  if (v2v) {
    v2v_ = open_csv(dir / "v2v.csv", "frame,vehicle,sequence,sensor_time_s,latitude_deg,"
                                     "longitude_deg,altitude_m,speed_mps,heading_rad");
  }
  flush();
  write_summary(nullptr);
}

RecorderAgent::~RecorderAgent() {
  for (std::FILE* f : {vehicles_, commands_, events_, gps_, imu_, compass_, wheel_speeds_, v2v_}) {
    if (f) std::fclose(f);
  }
}

std::vector<proto::Subscription> RecorderAgent::subscriptions() const {
  std::vector<proto::Subscription> subs = {{proto::Topic::vehicle_state, ""},
                                           {proto::Topic::driver_command, ""},
                                           {proto::Topic::collision_event, ""},
                                           {proto::Topic::vehicle_event, ""}};
  if (v2v_) subs.push_back({proto::Topic::v2v_message, ""});
  if (soil_) subs.push_back({proto::Topic::terrain_deformation, ""});
  if (gps_) {
    for (auto t : {proto::Topic::gps_fix, proto::Topic::imu, proto::Topic::magnetometer,
                   proto::Topic::wheel_speeds}) {
      subs.push_back({t, ""});
    }
  }
  return subs;
}

void RecorderAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                         proto::FrameSamples& outputs) {
  if (ctx.frame > 0) record(inputs);  // inputs are stamped ctx.frame - 1
  if (soil_) soil_->take_local_changes();  // opens the merge window of this frame's lists
}

void RecorderAgent::finish(const proto::RunEnd& end, const proto::FrameSamples& final_inputs) {
  if (!final_inputs.empty()) record(final_inputs);
  if (!followers_.empty()) write_convoy_report();
  if (end.control.status == proto::RunStatus::aborted) {
    note_event(last_frame_, "run_aborted", "", end.control.reason);
  } else {
    note_event(last_frame_, "run_completed", "", "");
  }
  flush();
  if (soil_) {
    try {
      scm::write_terrain_images(*soil_, (fs::path(options_.output_dir) / "terrain").string());
    } catch (const std::exception& e) {
      note_event(last_frame_, "error", "", std::string("terrain images: ") + e.what());
    }
  }
  write_summary(&end.control);
  finished_ = true;
}

void RecorderAgent::record(const proto::FrameSamples& samples) {
  fmt::memory_buffer out;
  for (const auto& s : samples.vehicle_states) {
    const double speed = s.linear_velocity.norm();
    const auto& p = s.pose.position;
    const auto& q = s.pose.orientation;
    const auto& v = s.linear_velocity;
    fmt::format_to(std::back_inserter(out),
                   "{},{:.9g},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},"
                   "{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{},{:.9g}\n",
                   s.frame, s.sim_time_s, s.vehicle_id, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(),
                   q.z(), v.x(), v.y(), v.z(), speed, s.steering, s.throttle, s.braking, s.gear,
                   s.engine_speed_rpm);
    VehicleTotals& t = totals_[s.vehicle_id];
    if (t.samples > 0) t.distance_m += (p - t.last_position).norm();
    t.last_position = p;
    t.speed_sum_mps += speed;
    t.max_speed_mps = std::max(t.max_speed_mps, speed);
    ++t.samples;
    last_frame_ = std::max(last_frame_, s.frame);
    if (!followers_.empty()) {
      tracks_[s.vehicle_id].push_back({s.sim_time_s, Vec2(p.x(), p.y()), speed});
    }
  }
  std::fwrite(out.data(), 1, out.size(), vehicles_);
  out.clear();
  for (const auto& c : samples.driver_commands) {
    // `rejected`: the vehicle refuses it (NaN, out of range; the reason is in events.csv).
    fmt::format_to(std::back_inserter(out), "{},{:.9g},{},{},{:.9g},{:.9g},{:.9g},{}\n", c.frame,
                   static_cast<double>(c.frame) * heartbeat_s_, c.vehicle_id, c.source, c.steering,
                   c.throttle, c.braking, proto::validate_command(c).empty() ? 0 : 1);
    last_frame_ = std::max(last_frame_, c.frame);
  }
  std::fwrite(out.data(), 1, out.size(), commands_);
  out.clear();
  for (const auto& e : samples.collision_events) {
    fmt::format_to(std::back_inserter(out), "{},{:.9g},collision,{},obstacle={} impulse_ns={:.6g}\n",
                   e.frame, e.sim_time_s, e.vehicle_id, csv_safe(e.obstacle_id), e.impulse_ns);
    ++totals_[e.vehicle_id].collisions;
  }
  for (const auto& e : samples.vehicle_events) {
    fmt::format_to(std::back_inserter(out), "{},{:.9g},{},{},{}\n", e.frame, e.sim_time_s,
                   csv_safe(e.kind), e.vehicle_id, csv_safe(e.source + ": " + e.detail));
    ++totals_[e.vehicle_id].events[e.kind];
  }
  std::fwrite(out.data(), 1, out.size(), events_);
  if (v2v_) {
    out.clear();
    for (const auto& m : samples.v2v_messages) {
      fmt::format_to(std::back_inserter(out), "{},{},{},{:.9g},{:.10f},{:.10f},{:.4f},{:.6g},{:.6g}\n",
                     m.frame, m.vehicle_id, m.sequence, m.sensor_time_s, m.latitude_deg,
                     m.longitude_deg, m.altitude_m, m.speed_mps, m.heading_rad);
    }
    std::fwrite(out.data(), 1, out.size(), v2v_);
  }
  if (gps_) record_sensors(samples);
  flush();
  if (soil_) {
    std::uint64_t frame_bytes = 0;
    for (const auto& d : samples.terrain_deformations) {
      soil_->apply_remote_changes(d.source_index, agents::from_messages(d.vertices));
      frame_bytes += d.vertices.size() * sizeof(proto::TerrainVertexMsg);
    }
    terrain_bytes_ += frame_bytes;
    terrain_max_frame_bytes_ = std::max(terrain_max_frame_bytes_, frame_bytes);
  }
}

void RecorderAgent::record_sensors(const proto::FrameSamples& samples) {
  fmt::memory_buffer out;
  auto stamp = [&](const auto& m) {
    fmt::format_to(std::back_inserter(out), "{},{},{},{},{:.9g},{:.9g},", m.frame, m.vehicle_id,
                   m.stamp.sensor_id, m.stamp.sequence, m.stamp.time_s, m.stamp.available_s);
  };
  for (const auto& m : samples.gps_fixes) {
    stamp(m);
    fmt::format_to(std::back_inserter(out), "{:.10f},{:.10f},{:.4f},{:.4f},{:.4f},{:.4f}\n",
                   m.latitude_deg, m.longitude_deg, m.altitude_m, m.enu_m.x(), m.enu_m.y(),
                   m.enu_m.z());
  }
  std::fwrite(out.data(), 1, out.size(), gps_);
  out.clear();
  for (const auto& m : samples.imus) {
    stamp(m);
    fmt::format_to(std::back_inserter(out), "{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g}\n",
                   m.accel_mps2.x(), m.accel_mps2.y(), m.accel_mps2.z(), m.gyro_rad_s.x(),
                   m.gyro_rad_s.y(), m.gyro_rad_s.z());
  }
  std::fwrite(out.data(), 1, out.size(), imu_);
  out.clear();
  for (const auto& m : samples.magnetometers) {
    stamp(m);
    fmt::format_to(std::back_inserter(out), "{:.6g},{:.6g},{:.6g},{:.6g}\n", m.heading_rad,
                   m.field_ut.x(), m.field_ut.y(), m.field_ut.z());
  }
  std::fwrite(out.data(), 1, out.size(), compass_);
  out.clear();
  for (const auto& m : samples.wheel_speeds) {
    stamp(m);
    for (std::size_t i = 0; i < 4; ++i) {
      fmt::format_to(std::back_inserter(out), "{:.6g}{}",
                     i < m.wheel_spin_rad_s.size() ? m.wheel_spin_rad_s[i] : 0.0, i < 3 ? "," : "\n");
    }
  }
  std::fwrite(out.data(), 1, out.size(), wheel_speeds_);
}

void RecorderAgent::note_event(std::int64_t frame, const std::string& kind,
                               const std::string& vehicle, const std::string& detail) {
  const double t = frame >= 0 ? static_cast<double>(frame) * heartbeat_s_ : 0.0;
  fmt::print(events_, "{},{:.9g},{},{},{}\n", frame, t, kind, csv_safe(vehicle), csv_safe(detail));
  std::fflush(events_);
}

void RecorderAgent::flush() {
  for (std::FILE* f : {vehicles_, commands_, events_, gps_, imu_, compass_, wheel_speeds_, v2v_}) {
    if (f) std::fflush(f);
  }
}

void RecorderAgent::write_convoy_report() {
  convoy_.clear();
  for (const auto& [follower, leader] : followers_) {
    const VehicleTotals& t = totals_.at(follower);
    const auto lost = t.events.find("leader_lost");
    convoy_.push_back(convoy::follower_report(follower, leader, tracks_[follower], tracks_[leader],
                                              t.collisions,
                                              lost == t.events.end() ? 0 : lost->second));
  }
  write_text_atomically(fs::path(options_.output_dir) / "convoy.json",
                        convoy_json(convoy_).dump(2) + "\n");
}

void RecorderAgent::write_summary(const proto::RunControlMsg* end) {
  using nlohmann::json;
  json j;
  j["scenario"] = scenario_name_;
  j["scenario_file"] = scenario_file_;
  j["run_id"] = options_.run_id;
  j["mode"] = options_.mode;
  j["heartbeat_s"] = heartbeat_s_;
  j["recorded_up_to_frame"] = last_frame_;
  if (!end) {
    j["status"] = "running";
  } else {
    const auto& st = end->stats;
    j["status"] = std::string(proto::to_string(end->status));
    j["reason"] = end->reason;
    j["frames"] = st.frames;
    j["final_frame"] = st.final_frame;
    j["sim_time_s"] = st.sim_time_s;
    j["wall_time_s"] = st.wall_time_s;
    j["real_time_factor"] = st.real_time_factor;
    json members = json::array();
    for (const auto& m : st.members) {
      members.push_back({{"member", m.member_id},
                         {"mean_response_s", m.mean_response_s},
                         {"max_response_s", m.max_response_s},
                         {"mean_compute_s", m.mean_compute_s},
                         {"slowest_frames", m.slowest_count},
                         {"lost", m.lost}});
    }
    j["members"] = members;
  }
  if (!end) {
    j["members"] = members_;
  }
  json vehicles = json::array();
  for (const auto& id : vehicle_ids_) {
    const VehicleTotals& t = totals_.at(id);
    vehicles.push_back({{"id", id},
                        {"distance_m", t.distance_m},
                        {"mean_speed_mps", t.mean_speed_mps()},
                        {"max_speed_mps", t.max_speed_mps},
                        {"collisions", t.collisions},
                        {"events", t.events},
                        {"final_position", {t.last_position.x(), t.last_position.y(),
                                            t.last_position.z()}}});
  }
  j["vehicles"] = vehicles;
  if (soil_) {
    const double frames = static_cast<double>(std::max<std::int64_t>(1, last_frame_ + 1));
    j["terrain"] = {{"deformation_bytes_total", terrain_bytes_},
                    {"deformation_bytes_per_frame_mean", static_cast<double>(terrain_bytes_) / frames},
                    {"deformation_bytes_per_frame_max", terrain_max_frame_bytes_},
                    {"grid_hash", fmt::format("{:016x}", soil_->grid_hash())}};
  }
  if (!convoy_.empty()) j["convoy"] = convoy_json(convoy_);
  const fs::path dir(options_.output_dir);
  write_text_atomically(dir / "summary.json", j.dump(2) + "\n");

  // The same, for a person.
  std::string text;
  if (!end) {
    text = fmt::format("run '{}' is running (output {})\n", scenario_name_, options_.output_dir);
  } else {
    const auto& st = end->stats;
    text += fmt::format("run '{}' {}{}\n", scenario_name_, proto::to_string(end->status),
                        end->reason.empty() ? "" : ": " + end->reason);
    text += fmt::format("  {} frames, {:.2f} s simulated in {:.2f} s wall, real-time factor {:.3f}\n",
                        st.frames, st.sim_time_s, st.wall_time_s, st.real_time_factor);
    text += fmt::format("  {:<12} {:>12} {:>15} {:>14} {:>11}\n", "vehicle", "distance_m",
                        "mean_speed_mps", "max_speed_mps", "collisions");
    for (const auto& id : vehicle_ids_) {
      const VehicleTotals& t = totals_.at(id);
      text += fmt::format("  {:<12} {:>12.1f} {:>15.2f} {:>14.2f} {:>11}\n", id, t.distance_m,
                          t.mean_speed_mps(), t.max_speed_mps, t.collisions);
    }
    if (!st.members.empty() && options_.mode == "distributed") {
      text += fmt::format("  {:<22} {:>16} {:>15} {:>13}\n", "member", "mean_response_ms",
                          "max_response_ms", "slowest_frames");
      for (const auto& m : st.members) {
        text += fmt::format("  {:<22} {:>16.3f} {:>15.3f} {:>13}{}\n", m.member_id,
                            m.mean_response_s * 1e3, m.max_response_s * 1e3, m.slowest_count,
                            m.lost ? "  (lost)" : "");
      }
    }
    if (!convoy_.empty()) text += convoy_table(convoy_);
  }
  write_text_atomically(dir / "summary.txt", text);
}

}  // namespace syndds::record
