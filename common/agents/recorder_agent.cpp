#include "agents/recorder_agent.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <charconv>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "agents/scm_messages.hpp"
#include "core/error.hpp"
#include "protocol/admission.hpp"
#include "protocol/vertex_codec.hpp"
#include "scm/scm_images.hpp"
#include "viewer/scene.hpp"

namespace syndds::record {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

// How often summary.json is brought up to date while the run goes on (wall time).
constexpr double kSummaryPeriodS = 1.0;
// Held back until the end, so that the summary saying why the run ended fits on a full disk
// (summary.json and summary.txt of a large scenario take a few tens of kB).
constexpr const char* kReserveFile = ".summary_reserve";
constexpr std::uint64_t kReserveBytes = 256 * 1024;

const std::vector<std::string> kVehicleColumns = {
    "frame", "time_s", "vehicle", "x", "y", "z", "qw", "qx", "qy", "qz", "vx", "vy", "vz",
    "speed_mps", "steering", "throttle", "braking", "gear", "engine_speed_rpm"};
const std::vector<std::string> kCommandColumns = {"frame",    "time_s",  "vehicle", "source",
                                                  "steering", "throttle", "braking", "rejected"};
const std::vector<std::string> kEventColumns = {"frame", "time_s", "kind", "vehicle", "detail"};
// wheels.csv: what a replay needs to draw the wheels (docs/outputs.md); 0 FL, 1 FR, 2 RL, 3 RR.
const std::vector<std::string> kWheelColumns = {"frame", "vehicle", "wheel", "x",  "y", "z",
                                                "qw",    "qx",      "qy",    "qz", "spin_rad_s"};
// terrain_changes.csv: soil vertices (x = i * spacing, y = j * spacing) whose surface height
// changed since the previous snapshot, with their height at `frame`.
const std::vector<std::string> kTerrainChangeColumns = {"frame", "i", "j", "height"};
// Snapshots of the soil for replay, in simulated seconds.
constexpr double kTerrainSnapshotS = 0.25;
const std::vector<std::string> kV2VColumns = {
    "frame",         "vehicle",    "sequence",  "sensor_time_s", "latitude_deg",
    "longitude_deg", "altitude_m", "speed_mps", "heading_rad"};
// The paper's settings of the deviation metrics (docs/convoy.md).
const metrics::Settings kMetricsSettings{};
// metrics_samples.csv: each follower's samples along its leader's path (docs/convoy.md).
const std::vector<std::string> kMetricsSampleColumns = {
    "follower", "position", "leader", "arc_m", "path_m", "leader_speed_mps", "follower_speed_mps"};

// Interoceptive sensor files: the stamp columns, then the sensor's own.
std::vector<std::string> stamped(std::initializer_list<const char*> values) {
  std::vector<std::string> c = {"frame", "vehicle", "sensor", "sequence", "time_s", "available_s"};
  c.insert(c.end(), values.begin(), values.end());
  return c;
}

template <typename Msg, typename... Values>
void stamped_row(CsvFile& f, const Msg& m, const Values&... values) {
  f.row(m.frame, m.vehicle_id, m.stamp.sensor_id, m.stamp.sequence, m.stamp.time_s,
        m.stamp.available_s, values...);
}

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

convoy::BodyBox body_box(const vehicle::VehicleParams& p) {
  return {p.chassis.box_centre_m, p.chassis.half_extents_m};
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
                   {"bumper_gap_m", stat_json(r.bumper_gap_m)},
                   {"min_bumper_gap_time_s", r.min_bumper_gap_time_s},
                   {"standstill_bumper_m", r.standstill_bumper_m},
                   {"time_below_standstill_s", r.time_below_standstill_s},
                   {"obstacles_hit", r.obstacles_hit},
                   {"vehicle_contacts", r.vehicle_contacts},
                   {"leader_lost_events", r.leader_lost_events},
                   {"stuck", r.stuck},
                   {"stuck_time_s", r.stuck_time_s}});
  }
  return out;
}

// Numbers of metrics.json: 9 significant digits, as in every other file (JSON writes the
// shortest text that reads back as the rounded value). from_chars: no locale can change it.
double sig9(double v) {
  const std::string text = fmt::format("{:.9g}", v);
  double rounded = v;
  std::from_chars(text.data(), text.data() + text.size(), rounded);
  return rounded;
}

nlohmann::json metrics_json(const std::vector<FollowerMetrics>& all,
                            const std::map<std::string, metrics::SpeedSummary>& leaders,
                            const metrics::Settings& settings) {
  // A deviation without samples has no value: null, not 0.
  const auto value = [](const metrics::Deviation& d, double v) {
    return d.samples > 0 ? nlohmann::json(sig9(v)) : nlohmann::json(nullptr);
  };
  nlohmann::json followers = nlohmann::json::array();
  for (const auto& m : all) {
    const metrics::Deviations& d = m.deviations;
    followers.push_back({{"id", m.follower},
                         {"leader", m.chain.leader},
                         {"follows", m.chain.follows},
                         {"position", m.chain.position},
                         {"m_p_avg", value(d.path_m, d.path_m.avg)},
                         {"m_p_max", value(d.path_m, d.path_m.max)},
                         {"m_as_avg", value(d.abs_speed_mps, d.abs_speed_mps.avg)},
                         {"m_as_max", value(d.abs_speed_mps, d.abs_speed_mps.max)},
                         {"m_rs_avg", value(d.rel_speed, d.rel_speed.avg)},
                         {"m_rs_max", value(d.rel_speed, d.rel_speed.max)},
                         {"obstacles_hit", m.obstacles_hit},
                         {"vehicle_contacts", m.vehicle_contacts},
                         {"min_bumper_gap_m", sig9(m.min_bumper_gap_m)},
                         {"time_below_standstill_s", sig9(m.time_below_standstill_s)},
                         {"samples", d.samples},
                         {"speed_samples", d.abs_speed_mps.samples},
                         {"relative_speed_samples", d.rel_speed.samples},
                         {"segment_length_m", sig9(d.leader_segment_m)},
                         {"follower_segment_length_m", sig9(d.follower_segment_m)},
                         {"follower_start_time_s", sig9(m.follower_start_time_s)},
                         {"leader_end_time_s", sig9(m.leader_end_time_s)}});
  }
  nlohmann::json heads = nlohmann::json::array();
  for (const auto& [id, s] : leaders) {
    heads.push_back({{"id", id},
                     {"max_speed_mps", sig9(s.max_mps)},
                     {"mean_moving_speed_mps", sig9(s.mean_moving_mps)},
                     {"distance_m", sig9(s.distance_m)}});
  }
  return {{"spacing_m", settings.spacing_m},
          {"speed_skip_m", settings.speed_skip_m},
          {"min_leader_speed_mps", settings.min_leader_speed_mps},
          {"followers", followers},
          {"leaders", heads}};
}

metrics::Trajectory trajectory_of(const convoy::Track& track) {
  metrics::Trajectory t;
  t.reserve(track.size());
  for (const auto& p : track) t.push_back({p.time_s, p.position, p.speed_mps});
  return t;
}

// The paper's six metrics per follower, against the head of its chain (metrics.json).
std::string metrics_table(const std::vector<FollowerMetrics>& all) {
  const auto cell = [](const metrics::Deviation& d, double v, int decimals) {
    return d.samples > 0 ? fmt::format("{:.{}f}", v, decimals) : std::string("-");
  };
  std::string text = fmt::format("  {:<10} {:<8} {:>8} {:>14} {:>16} {:>16}\n", "follower",
                                 "leader", "position", "m_p m avg/max", "m_as m/s avg/max",
                                 "m_rs avg/max");
  for (const auto& m : all) {
    const metrics::Deviations& d = m.deviations;
    text += fmt::format(
        "  {:<10} {:<8} {:>8} {:>14} {:>16} {:>16}\n", m.follower, m.chain.leader,
        m.chain.position,
        cell(d.path_m, d.path_m.avg, 2) + "/" + cell(d.path_m, d.path_m.max, 2),
        cell(d.abs_speed_mps, d.abs_speed_mps.avg, 2) + "/" +
            cell(d.abs_speed_mps, d.abs_speed_mps.max, 2),
        cell(d.rel_speed, d.rel_speed.avg, 3) + "/" + cell(d.rel_speed, d.rel_speed.max, 3));
  }
  return text;
}

std::string convoy_table(const std::vector<convoy::FollowerReport>& reports) {
  // Gaps in metres and seconds, cross-track in metres (definitions: docs/convoy.md).
  // Bumper: the smallest box-to-box gap, and the time spent below the standstill gap.
  std::string text = fmt::format(
      "  {:<10} {:<8} {:>20} {:>20} {:>15} {:>15} {:>9} {:>8} {:>11} {:>9}\n", "follower",
      "follows", "gap m mean/min/max", "gap s mean/min/max", "cross m mean/max",
      "bumper m min/<s", "obstacles", "contacts", "leader_lost", "stuck at");
  for (const auto& r : reports) {
    text += fmt::format("  {:<10} {:<8} {:>20} {:>20} {:>15} {:>15} {:>9} {:>8} {:>11} {:>9}\n",
                        r.follower,
                        r.leader,
                        fmt::format("{:.1f}/{:.1f}/{:.1f}", r.distance_gap_m.mean,
                                    r.distance_gap_m.min, r.distance_gap_m.max),
                        fmt::format("{:.2f}/{:.2f}/{:.2f}", r.time_gap_s.mean, r.time_gap_s.min,
                                    r.time_gap_s.max),
                        fmt::format("{:.2f}/{:.2f}", r.cross_track_m.mean, r.cross_track_m.max),
                        fmt::format("{:.2f}/{:.2f}", r.bumper_gap_m.min, r.time_below_standstill_s),
                        r.obstacles_hit, r.vehicle_contacts, r.leader_lost_events,
                        r.stuck ? fmt::format("{:.1f} s", r.stuck_time_s) : "-");
  }
  return text;
}

}  // namespace

RecorderAgent::RecorderAgent(const scenario::Scenario& scenario, RecorderOptions options)
    : options_(std::move(options)),
      scenario_name_(scenario.name),
      scenario_file_(scenario.file),
      heartbeat_s_(scenario.time.heartbeat_s),
      members_(scenario.member_ids()),
      started_(Clock::now()) {
  bool v2v = false;
  for (const auto& v : scenario.vehicles) {
    vehicle_ids_.push_back(v.id);
    totals_[v.id];
    v2v = v2v || v.v2v.has_value();
    if (v.controller.follows()) followers_.emplace_back(v.id, v.controller.convoy.leader);
    for (const auto& m : {scenario::vehicle_member(v.id), scenario::controller_member(v.id),
                          scenario::external_member(v.id), scenario::sensor_member(v.id)}) {
      vehicle_of_member_[m] = v.id;
    }
  }
  for (const auto& [follower, leader] : followers_) {
    const auto* f = scenario.find_vehicle(follower);
    const auto* l = scenario.find_vehicle(leader);
    if (!f || !l) continue;  // the scenario's own checks refuse this; chains_ below names it
    gap_geometry_[follower] = {body_box(f->params), body_box(l->params),
                               f->controller.convoy.standstill_bumper_m};
  }
  // Each follower is measured against the head of its chain: a chain must have one, which
  // the scenario's own checks (each follower follows another vehicle) do not ensure.
  try {
    chains_ = metrics::resolve_chains({followers_.begin(), followers_.end()});
  } catch (const std::invalid_argument& e) {
    throw ConfigError(scenario.file + ": vehicles: controller.follow: " + e.what());
  }
  if (scenario.terrain.deformable()) {
    soil_ = std::make_unique<scm::ScmTerrain>(scenario.terrain.scm);
    soil_->set_source_id(static_cast<std::uint32_t>(members_.size()));  // never wins a tie
    routing_ = scenario.terrain.scm.routing;
  }
  const fs::path dir(options_.output_dir);
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw ConfigError(dir.string() + ": cannot create output directory: " + ec.message());
  const auto open = options_.resume ? OutputFile::Open::resume : OutputFile::Open::create;
  reserve_ = std::make_unique<SpaceReserve>(dir / kReserveFile, kReserveBytes);
  vehicles_ = std::make_unique<CsvFile>(dir / "vehicles.csv", kVehicleColumns, open);
  const auto& rec = scenario.recorder;
  if (rec.records("commands")) {
    commands_ = std::make_unique<CsvFile>(dir / "commands.csv", kCommandColumns, open);
  }
  events_ = std::make_unique<CsvFile>(dir / "events.csv", kEventColumns, open);
  if (rec.records("wheels")) {
    wheels_ = std::make_unique<CsvFile>(dir / "wheels.csv", kWheelColumns, open);
  }
  if (soil_) {
    terrain_changes_ =
        std::make_unique<CsvFile>(dir / "terrain_changes.csv", kTerrainChangeColumns, open);
    terrain_every_ = std::max<std::int64_t>(
        1, std::llround(kTerrainSnapshotS / scenario.time.heartbeat_s));
  }
  // What a viewer draws the world from (docs/viewer.md): derived from the scenario alone.
  write_file_atomically(dir / "scene.json", viewer::scene_json(scenario).dump() + "\n");
  bool interoceptive = false;
  for (const auto& v : scenario.vehicles) interoceptive = interoceptive || v.has_interoceptive_sensors();
  if (interoceptive && rec.records("gps")) {
    gps_ = std::make_unique<CsvFile>(
        dir / "gps.csv",
        stamped({"latitude_deg", "longitude_deg", "altitude_m", "e_m", "n_m", "u_m"}), open);
  }
  if (interoceptive && rec.records("imu")) {
    imu_ = std::make_unique<CsvFile>(
        dir / "imu.csv",
        stamped({"ax_mps2", "ay_mps2", "az_mps2", "gx_rad_s", "gy_rad_s", "gz_rad_s"}), open);
  }
  if (interoceptive && rec.records("compass")) {
    compass_ = std::make_unique<CsvFile>(dir / "compass.csv",
                                         stamped({"heading_rad", "fx_ut", "fy_ut", "fz_ut"}), open);
  }
  if (interoceptive && rec.records("wheel_speeds")) {
    wheel_speeds_ = std::make_unique<CsvFile>(
        dir / "wheel_speeds.csv", stamped({"fl_rad_s", "fr_rad_s", "rl_rad_s", "rr_rad_s"}), open);
  }
  if (v2v && rec.records("v2v")) {
    v2v_ = std::make_unique<CsvFile>(dir / "v2v.csv", kV2VColumns, open);
  }
  bool radar = false;
  for (const auto& v : scenario.vehicles) radar = radar || (v.sensors && !v.sensors->rig.radars.empty());
  if (radar && rec.records("radar")) {
    radar_ = std::make_unique<CsvFile>(
        dir / "radar.csv",
        stamped({"detection", "range_m", "azimuth_rad", "elevation_rad", "radial_speed_mps",
                 "strength_db", "rcs_dbsm", "points", "x", "y", "z", "world_x", "world_y",
                 "world_z"}),
        open);
  }
  write_summary(nullptr);
}

std::vector<proto::Subscription> RecorderAgent::subscriptions() const {
  // A file that is not written is not subscribed to (RecorderConfig::skip).
  std::vector<proto::Subscription> subs = {{proto::Topic::vehicle_state, ""}};
  if (commands_) subs.push_back({proto::Topic::driver_command, ""});
  subs.push_back({proto::Topic::collision_event, ""});
  subs.push_back({proto::Topic::vehicle_event, ""});
  if (v2v_) subs.push_back({proto::Topic::v2v_message, ""});
  if (soil_) subs.push_back({proto::Topic::terrain_deformation, ""});
  if (routing_) subs.push_back({proto::Topic::soil_interest, ""});
  if (gps_) subs.push_back({proto::Topic::gps_fix, ""});
  if (imu_) subs.push_back({proto::Topic::imu, ""});
  if (compass_) subs.push_back({proto::Topic::magnetometer, ""});
  if (wheel_speeds_) subs.push_back({proto::Topic::wheel_speeds, ""});
  if (radar_) subs.push_back({proto::Topic::radar, ""});
  return subs;
}

std::vector<proto::Topic> RecorderAgent::publications() const {
  if (!routing_) return {};
  return {proto::Topic::terrain_patch, proto::Topic::terrain_snapshot};
}

template <typename F>
void RecorderAgent::guarded(F&& write) {
  if (!failure_.empty()) throw WriteError("the recorder failed earlier: " + failure_);
  try {
    write();
  } catch (const WriteError& e) {
    failure_ = e.what();
    throw;
  }
}

void RecorderAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                         proto::FrameSamples& outputs) {
  guarded([&] {
    if (ctx.frame > 0) record(inputs, ctx.frame - 1);  // inputs are stamped ctx.frame - 1
    if (routing_) keep_soil(ctx, inputs, outputs);
    // Members lost since the last frame (on_member_loss: continue): gone from this frame on.
    for (const auto& member : ctx.departed) {
      losses_.push_back({member, ctx.frame, ctx.sim_time_s});
      const auto v = vehicle_of_member_.find(member);
      events_->row(ctx.frame, ctx.sim_time_s, "member_lost",
                   v == vehicle_of_member_.end() ? std::string() : v->second, member);
    }
    for (const auto& entry : ctx.intrusions) {
      Intrusion i;
      i.frame = ctx.frame;
      if (!proto::split_member_entry(entry, i.member, i.participant, &i.what)) continue;
      const auto v = vehicle_of_member_.find(i.member);
      events_->row(ctx.frame, ctx.sim_time_s, "intrusion",
                   v == vehicle_of_member_.end() ? std::string() : v->second,
                   "participant " + i.participant + " as " + i.member + ": " + i.what);
      intrusions_.push_back(std::move(i));
    }
    commit();
    if (seconds_since(summary_written_) >= kSummaryPeriodS) write_summary(nullptr);
  });
  if (soil_) soil_->take_local_changes();  // opens the merge window of this frame's lists
}

// What soil routing sends each vehicle of these lists (frame k-1's, the writers addressed them
// by the boxes published up to frame k-2, which soil_boxes_ holds until keep_soil), packed as
// they travel: the traffic a vehicle receives, for the summary.
void RecorderAgent::count_routed(const proto::FrameSamples& samples) {
  for (const auto& d : samples.terrain_deformations) {
    for (const auto& [id, box] : soil_boxes_.boxes()) {
      if (id == d.vehicle_id) continue;
      const auto in_box = agents::records_in(d.vertices, box);
      if (!in_box.empty()) routed_bytes_[id] += proto::packed_size(in_box);
    }
  }
}

// The soil keeper (routing): the recorder's copy has merged every list up to frame k-1. A
// vehicle whose box grew in frame k-1 gets what that copy holds in the tiles it gained (boxes of
// frame 0 start on untouched soil); a late joiner gets the whole copy and merges the lists of
// frame k itself.
void RecorderAgent::keep_soil(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                              proto::FrameSamples& outputs) {
  for (const auto& change : soil_boxes_.update(inputs.soil_interests, "")) {
    if (change.frame == 0) continue;
    const auto state = soil_->added_tiles_state(change.now, change.before);
    if (state.empty()) continue;
    proto::TerrainPatchMsg m{change.vehicle_id, scenario::kRecorderMember, ctx.frame,
                             soil_->source_id(), soil_->spacing(), true, {}};
    m.vertices.reserve(state.size());
    for (const auto& c : state) m.vertices.push_back(agents::to_message(c));
    routed_bytes_[change.vehicle_id] += proto::packed_size(m.vertices);
    outputs.terrain_patches.push_back(std::move(m));
  }
  if (!ctx.joiners.empty()) {
    const scm::ScmSnapshot snap = soil_->snapshot();
    proto::TerrainSnapshotMsg m{"", scenario::kRecorderMember, ctx.frame,  // key: no vehicle
                               snap.spacing_m, {}};
    m.vertices.reserve(snap.vertices.size());
    for (const auto& v : snap.vertices) m.vertices.push_back(agents::to_message(v));
    outputs.terrain_snapshots.push_back(std::move(m));
  }
}

void RecorderAgent::finish(const proto::RunEnd& end, const proto::FrameSamples& final_inputs) {
  finished_ = true;
  // After a write error (it ended the run) the files stay as they were: only whole frames.
  if (failure_.empty()) {
    try {
      guarded([&] {
        if (!final_inputs.empty()) record(final_inputs, end.control.final_frame);
        if (terrain_changes_ && !changed_vertices_.empty()) {
          record_terrain_changes(std::max<std::int64_t>(last_frame_, pending_frame_));
        }
        commit();
        if (!followers_.empty()) {
          write_convoy_report();
          write_metrics();
        }
        if (end.control.status == proto::RunStatus::aborted) {
          note_event(last_frame_, "run_aborted", "", end.control.reason);
        } else {
          note_event(last_frame_, "run_completed", "", "");
        }
        if (soil_) {
          try {
            scm::write_terrain_images(*soil_,
                                      (fs::path(options_.output_dir) / "terrain").string());
          } catch (const WriteError&) {
            throw;
          } catch (const std::exception& e) {
            note_event(last_frame_, "error", "", std::string("terrain images: ") + e.what());
          }
        }
      });
    } catch (const WriteError& e) {
      spdlog::error("recorder: {}", e.what());
    }
  }
  // The summary says how the run ended even when the files above could not be completed (the
  // failure is in it); if it cannot be written either, the last one written stays.
  reserve_.reset();
  try {
    write_summary(&end.control);
  } catch (const WriteError& e) {
    spdlog::error("recorder: {}", e.what());
    if (failure_.empty()) failure_ = e.what();
  }
  // A run that otherwise completed must not look complete when its record is not.
  if (end.control.status == proto::RunStatus::completed && !failure_.empty()) {
    throw WriteError(failure_);
  }
}

void RecorderAgent::record(const proto::FrameSamples& samples, std::int64_t frame) {
  for (const auto& s : samples.vehicle_states) {
    const double speed = s.linear_velocity.norm();
    const auto& p = s.pose.position;
    const auto& q = s.pose.orientation;
    const auto& v = s.linear_velocity;
    vehicles_->row(s.frame, s.sim_time_s, s.vehicle_id, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(),
                   q.z(), v.x(), v.y(), v.z(), speed, s.steering, s.throttle, s.braking, s.gear,
                   s.engine_speed_rpm);
    VehicleTotals& t = totals_[s.vehicle_id];
    if (t.samples > 0) t.distance_m += (p - t.last_position).norm();
    t.last_position = p;
    t.speed_sum_mps += speed;
    t.max_speed_mps = std::max(t.max_speed_mps, speed);
    ++t.samples;
    pending_frame_ = std::max(pending_frame_, s.frame);
    for (std::size_t w = 0; wheels_ && w < s.wheels.size(); ++w) {  // wheels_: not skipped
      const auto& wp = s.wheels[w].pose.position;
      const auto& wq = s.wheels[w].pose.orientation;
      wheels_->row(s.frame, s.vehicle_id, w, wp.x(), wp.y(), wp.z(), wq.w(), wq.x(), wq.y(),
                   wq.z(), Sig{s.wheels[w].spin_rad_s, 6});
    }
    if (!followers_.empty()) {
      tracks_[s.vehicle_id].push_back({s.sim_time_s, Vec2(p.x(), p.y()), speed, p.z(), q});
    }
  }
  // A skipped file's topic is not subscribed to, so its samples never come here.
  if (commands_) {
    for (const auto& c : samples.driver_commands) {
      // `rejected`: the vehicle refuses it (NaN, out of range; the reason is in events.csv).
      commands_->row(c.frame, static_cast<double>(c.frame) * heartbeat_s_, c.vehicle_id,
                     c.source, c.steering, c.throttle, c.braking,
                     proto::validate_command(c).empty() ? 0 : 1);
      pending_frame_ = std::max(pending_frame_, c.frame);
    }
  }
  for (const auto& e : samples.collision_events) {
    if (!e.other_vehicle_id.empty()) {
      // Each of the two vehicles reports its own (docs/vehicle-contact.md).
      events_->row(e.frame, e.sim_time_s, "collision", e.vehicle_id,
                   fmt::format("vehicle={} impulse_ns={:.6g} relative_speed_mps={:.4g} "
                               "at={:.3f}/{:.3f}/{:.3f}",
                               e.other_vehicle_id, e.impulse_ns, e.relative_speed_mps,
                               e.position.x(), e.position.y(), e.position.z()));
      ++totals_[e.vehicle_id].events[kVehicleContact];
      continue;
    }
    events_->row(e.frame, e.sim_time_s, "collision", e.vehicle_id,
                 fmt::format("obstacle={} impulse_ns={:.6g} at={:.3f}/{:.3f}/{:.3f}",
                             e.obstacle_id, e.impulse_ns, e.position.x(), e.position.y(),
                             e.position.z()));
    ++totals_[e.vehicle_id].collisions;
  }
  for (const auto& e : samples.vehicle_events) {
    events_->row(e.frame, e.sim_time_s, e.kind, e.vehicle_id, e.source + ": " + e.detail);
    ++totals_[e.vehicle_id].events[e.kind];
  }
  if (v2v_) {
    for (const auto& m : samples.v2v_messages) {
      v2v_->row(m.frame, m.vehicle_id, m.sequence, m.sensor_time_s, Fixed{m.latitude_deg, 10},
                Fixed{m.longitude_deg, 10}, Fixed{m.altitude_m, 4}, Sig{m.speed_mps, 6},
                Sig{m.heading_rad, 6});
    }
  }
  record_sensors(samples);
  if (radar_) record_radar(samples);
  if (soil_) {
    std::uint64_t frame_bytes = 0;
    for (const auto& d : samples.terrain_deformations) {
      soil_->apply_remote_changes(d.source_index, agents::from_messages(d.vertices));
      for (const auto& v : d.vertices) changed_vertices_.emplace(v.j, v.i);
      // The vertex lists as they travel (packed), and how many records they hold.
      frame_bytes += proto::packed_size(d.vertices);
      terrain_vertices_ += d.vertices.size();
    }
    if (routing_) count_routed(samples);
    terrain_bytes_ += frame_bytes;
    terrain_max_frame_bytes_ = std::max(terrain_max_frame_bytes_, frame_bytes);
    if (frame % terrain_every_ == 0) record_terrain_changes(frame);
  }
}

void RecorderAgent::record_terrain_changes(std::int64_t frame) {
  // Every list of the frame is merged: these are the heights every vehicle's copy has.
  for (const auto& [j, i] : changed_vertices_) {
    terrain_changes_->row(frame, i, j, soil_->vertex_height(i, j));
  }
  changed_vertices_.clear();
}

void RecorderAgent::record_sensors(const proto::FrameSamples& samples) {
  // Each file only when it is written (no sensors, or skipped: its topic is not subscribed to).
  if (gps_) {
    for (const auto& m : samples.gps_fixes) {
      stamped_row(*gps_, m, Fixed{m.latitude_deg, 10}, Fixed{m.longitude_deg, 10},
                  Fixed{m.altitude_m, 4}, Fixed{m.enu_m.x(), 4}, Fixed{m.enu_m.y(), 4},
                  Fixed{m.enu_m.z(), 4});
    }
  }
  if (imu_) {
    for (const auto& m : samples.imus) {
      stamped_row(*imu_, m, Sig{m.accel_mps2.x(), 6}, Sig{m.accel_mps2.y(), 6},
                  Sig{m.accel_mps2.z(), 6}, Sig{m.gyro_rad_s.x(), 6}, Sig{m.gyro_rad_s.y(), 6},
                  Sig{m.gyro_rad_s.z(), 6});
    }
  }
  if (compass_) {
    for (const auto& m : samples.magnetometers) {
      stamped_row(*compass_, m, Sig{m.heading_rad, 6}, Sig{m.field_ut.x(), 6},
                  Sig{m.field_ut.y(), 6}, Sig{m.field_ut.z(), 6});
    }
  }
  if (wheel_speeds_) {
    for (const auto& m : samples.wheel_speeds) {
      const auto spin = [&](std::size_t i) {
        return Sig{i < m.wheel_spin_rad_s.size() ? m.wheel_spin_rad_s[i] : 0.0, 6};
      };
      stamped_row(*wheel_speeds_, m, spin(0), spin(1), spin(2), spin(3));
    }
  }
}

void RecorderAgent::record_radar(const proto::FrameSamples& samples) {
  for (const auto& m : samples.radar_scans) {
    for (std::size_t k = 0; k < m.detections.size(); ++k) {
      const auto& d = m.detections[k];
      const Vec3 w = m.pose.position + m.pose.orientation * Vec3(d.x, d.y, d.z);
      stamped_row(*radar_, m, k, Fixed{d.range_m, 3}, Fixed{d.azimuth_rad, 5},
                  Fixed{d.elevation_rad, 5}, Fixed{d.radial_speed_mps, 3}, Fixed{d.strength_db, 2},
                  Fixed{d.rcs_dbsm, 2}, d.points, Fixed{d.x, 3}, Fixed{d.y, 3}, Fixed{d.z, 3},
                  Fixed{w.x(), 3}, Fixed{w.y(), 3}, Fixed{w.z(), 3});
    }
  }
}

void RecorderAgent::commit() {
  commit_rows({vehicles_.get(), commands_.get(), events_.get(), wheels_.get(),
               terrain_changes_.get(), gps_.get(), imu_.get(), compass_.get(), wheel_speeds_.get(),
               v2v_.get(), radar_.get()});
  last_frame_ = pending_frame_;
}

void RecorderAgent::note_event(std::int64_t frame, const std::string& kind,
                               const std::string& vehicle, const std::string& detail) {
  const double t = frame >= 0 ? static_cast<double>(frame) * heartbeat_s_ : 0.0;
  events_->row(frame, t, kind, vehicle, detail);
  events_->commit();
}

void RecorderAgent::write_convoy_report() {
  convoy_.clear();
  for (const auto& [follower, leader] : followers_) {
    const VehicleTotals& t = totals_.at(follower);
    const auto lost = t.events.find("leader_lost");
    convoy_.push_back(convoy::follower_report(
        follower, leader, tracks_[follower], tracks_[leader], t.collisions,
        lost == t.events.end() ? 0 : lost->second, gap_geometry_[follower], heartbeat_s_));
    convoy_.back().vehicle_contacts = t.vehicle_contacts();
  }
  write_file_atomically(fs::path(options_.output_dir) / "convoy.json",
                        convoy_json(convoy_).dump(2) + "\n");
}

void RecorderAgent::write_metrics() {
  const metrics::Settings& settings = kMetricsSettings;
  metrics_.clear();
  for (const auto& [follower, followed] : followers_) {
    FollowerMetrics m;
    m.follower = follower;
    m.chain = chains_.at(follower);
    const auto f = trajectory_of(tracks_[follower]);
    const auto l = trajectory_of(tracks_[m.chain.leader]);
    m.deviations = metrics::deviations(f, l, settings);
    if (!f.empty()) m.follower_start_time_s = f[m.deviations.follower_start_index].time_s;
    if (!l.empty()) m.leader_end_time_s = l[m.deviations.leader_end_index].time_s;
    m.obstacles_hit = totals_.at(follower).collisions;
    m.vehicle_contacts = totals_.at(follower).vehicle_contacts();
    for (const auto& r : convoy_) {
      if (r.follower != follower) continue;
      m.min_bumper_gap_m = r.bumper_gap_m.min;
      m.time_below_standstill_s = r.time_below_standstill_s;
    }
    metrics_.push_back(std::move(m));
  }
  // The heads of the follow chains: how fast they drove (soft soil may hold them back).
  leaders_.clear();
  for (const auto& m : metrics_) {
    if (!leaders_.contains(m.chain.leader)) {
      leaders_[m.chain.leader] =
          metrics::speed_summary(trajectory_of(tracks_[m.chain.leader]), settings);
    }
  }
  // The curves behind the averages, one row per sample of the leader's path.
  CsvFile samples(fs::path(options_.output_dir) / "metrics_samples.csv", kMetricsSampleColumns);
  for (const auto& m : metrics_) {
    for (const auto& x : m.deviations.series) {
      samples.row(m.follower, m.chain.position, m.chain.leader, x.arc_m, x.path_m,
                  x.leader_speed_mps, x.follower_speed_mps);
    }
  }
  samples.commit();
  samples.close();
  write_file_atomically(fs::path(options_.output_dir) / "metrics.json",
                        metrics_json(metrics_, leaders_, settings).dump(2) + "\n");
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
  // Without the coordinator's statistics (it was lost, or the run failed before it could send
  // them) the summary holds what the recorder knows itself, and says so.
  proto::RunStatsMsg st;
  const bool stats_missing = end && end->stats.members.empty();
  if (end && !stats_missing) {
    st = end->stats;
  } else if (end) {
    st.frames = static_cast<std::uint64_t>(last_frame_ + 1);
    st.final_frame = last_frame_;
    st.sim_time_s = last_frame_ > 0 ? static_cast<double>(last_frame_) * heartbeat_s_ : 0.0;
    st.wall_time_s = seconds_since(started_);
    st.real_time_factor = st.sim_time_s > 0 ? st.wall_time_s / st.sim_time_s : 0.0;
  }
  if (!end) {
    j["status"] = "running";
  } else {
    j["status"] = std::string(proto::to_string(end->status));
    j["reason"] = end->reason;
    j["frames"] = st.frames;
    j["final_frame"] = st.final_frame;
    j["sim_time_s"] = st.sim_time_s;
    j["wall_time_s"] = st.wall_time_s;
    j["real_time_factor"] = st.real_time_factor;
    if (stats_missing) {
      j["stats_missing"] = true;
      j["stats_note"] =
          "the coordinator's run statistics did not arrive: frames, final_frame and sim_time_s "
          "are what the recorder recorded, wall_time_s is the recorder's own";
    }
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
  json losses = json::array();
  for (const auto& l : losses_) {
    losses.push_back({{"member", l.member}, {"frame", l.frame}, {"time_s", l.time_s}});
  }
  j["losses"] = losses;
  json intrusions = json::array();
  for (const auto& i : intrusions_) {
    intrusions.push_back({{"member", i.member},
                          {"participant", i.participant},
                          {"what", i.what},
                          {"frame", i.frame}});
  }
  j["intrusions"] = intrusions;
  if (!failure_.empty()) j["recorder_error"] = failure_;
  json vehicles = json::array();
  for (const auto& id : vehicle_ids_) {
    const VehicleTotals& t = totals_.at(id);
    vehicles.push_back({{"id", id},
                        {"distance_m", t.distance_m},
                        {"mean_speed_mps", t.mean_speed_mps()},
                        {"max_speed_mps", t.max_speed_mps},
                        {"collisions", t.collisions},
                        {"vehicle_contacts", t.vehicle_contacts()},
                        {"events", t.events},
                        {"final_position", {t.last_position.x(), t.last_position.y(),
                                            t.last_position.z()}}});
  }
  j["vehicles"] = vehicles;
  if (soil_) {
    const double frames = static_cast<double>(std::max<std::int64_t>(1, last_frame_ + 1));
    j["terrain"] = {{"deformation_vertices_total", terrain_vertices_},
                    {"deformation_bytes_total", terrain_bytes_},
                    {"deformation_bytes_per_frame_mean", static_cast<double>(terrain_bytes_) / frames},
                    {"deformation_bytes_per_frame_max", terrain_max_frame_bytes_},
                    {"routing", routing_},
                    {"grid_hash", fmt::format("{:016x}", soil_->grid_hash())}};
    if (routing_) {
      // Per vehicle: the bytes of records addressed to it (the others' changes in its box and
      // the recorder's tiles as the box moved), per frame.
      nlohmann::json per_vehicle = nlohmann::json::object();
      nlohmann::json totals = nlohmann::json::object();
      double sum = 0.0;
      for (const auto& [id, bytes] : routed_bytes_) {
        per_vehicle[id] = static_cast<double>(bytes) / frames;
        totals[id] = bytes;
        sum += static_cast<double>(bytes) / frames;
      }
      j["terrain"]["routed_bytes_total"] = totals;
      j["terrain"]["routed_bytes_per_frame"] = per_vehicle;
      j["terrain"]["routed_bytes_per_vehicle_per_frame_mean"] =
          routed_bytes_.empty() ? 0.0 : sum / static_cast<double>(routed_bytes_.size());
    }
  }
  if (!convoy_.empty()) j["convoy"] = convoy_json(convoy_);
  if (!metrics_.empty()) j["metrics"] = metrics_json(metrics_, leaders_, kMetricsSettings);
  const fs::path dir(options_.output_dir);
  write_file_atomically(dir / "summary.json", j.dump(2) + "\n");

  // The same, for a person.
  std::string text;
  if (!end) {
    text = fmt::format("run '{}' is running (output {})\n", scenario_name_, options_.output_dir);
  } else {
    text += fmt::format("run '{}' {}{}\n", scenario_name_, proto::to_string(end->status),
                        end->reason.empty() ? "" : ": " + end->reason);
    text += fmt::format("  {} frames, {:.2f} s simulated in {:.2f} s wall, real-time factor {:.3f}\n",
                        st.frames, st.sim_time_s, st.wall_time_s, st.real_time_factor);
    if (stats_missing) {
      text += "  coordinator statistics missing: frames and times are what the recorder recorded\n";
    }
    if (!failure_.empty()) text += "  recorder error: " + failure_ + "\n";
    for (const auto& l : losses_) {
      text += fmt::format("  lost: {} in frame {} (t = {:.2f} s); the run went on without it\n",
                          l.member, l.frame, l.time_s);
    }
    for (const auto& i : intrusions_) {
      text += fmt::format("  intrusion (frame {}): participant {} as {}: {}\n", i.frame,
                          i.participant, i.member, i.what);
    }
    text += fmt::format("  {:<12} {:>12} {:>15} {:>14} {:>11} {:>16}\n", "vehicle", "distance_m",
                        "mean_speed_mps", "max_speed_mps", "collisions", "vehicle_contacts");
    for (const auto& id : vehicle_ids_) {
      const VehicleTotals& t = totals_.at(id);
      text += fmt::format("  {:<12} {:>12.1f} {:>15.2f} {:>14.2f} {:>11} {:>16}\n", id,
                          t.distance_m, t.mean_speed_mps(), t.max_speed_mps, t.collisions,
                          t.vehicle_contacts());
    }
    // Vehicle events by kind (command_rejected, leader_lost, ...): details in events.csv.
    for (const auto& id : vehicle_ids_) {
      const VehicleTotals& t = totals_.at(id);
      if (t.events.empty()) continue;
      std::string kinds;
      for (const auto& [kind, count] : t.events) {
        kinds += fmt::format("{}{} {}", kinds.empty() ? "" : ", ", kind, count);
      }
      text += fmt::format("  {} events: {} (events.csv)\n", id, kinds);
    }
    if (!st.members.empty() && options_.mode == "distributed") {
      // Response: grant sent to done received, as the coordinator saw it (members of one
      // process answer in one sample, so they share their process's). Step: the member's own
      // time in its step, which tells the members of a process apart.
      text += fmt::format("  {:<22} {:>16} {:>15} {:>12} {:>13}\n", "member", "mean_response_ms",
                          "max_response_ms", "mean_step_ms", "slowest_frames");
      for (const auto& m : st.members) {
        text += fmt::format("  {:<22} {:>16.3f} {:>15.3f} {:>12.3f} {:>13}{}\n", m.member_id,
                            m.mean_response_s * 1e3, m.max_response_s * 1e3,
                            m.mean_compute_s * 1e3, m.slowest_count, m.lost ? "  (lost)" : "");
      }
    }
    if (!convoy_.empty()) text += convoy_table(convoy_);
    if (!metrics_.empty()) text += metrics_table(metrics_);
  }
  write_file_atomically(dir / "summary.txt", text);
  summary_written_ = Clock::now();
}

}  // namespace syndds::record

namespace syndds::record {

std::vector<CsvFile*> RecorderAgent::files() const {
  return {vehicles_.get(), commands_.get(),     events_.get(),
          wheels_.get(),   terrain_changes_.get(), gps_.get(),
          imu_.get(),      compass_.get(),      wheel_speeds_.get(),
          v2v_.get(),      radar_.get()};
}

namespace {

// The recorder's state, one field list per record for saving and loading (a writer only
// reads what it is given).
template <typename Archive>
void totals_fields(Archive& a, VehicleTotals& t) {
  a.io(t.distance_m);
  a.io(t.speed_sum_mps);
  a.io(t.max_speed_mps);
  a.io(t.samples);
  a.io(t.collisions);
  std::uint64_t n = t.events.size();
  a.io(n);
  if constexpr (std::is_same_v<Archive, core::StateWriter>) {
    for (const auto& [kind, count] : t.events) {
      a.io(kind);
      a.io(count);
    }
  } else {
    t.events.clear();
    for (std::uint64_t k = 0; k < n; ++k) {
      const auto kind = a.template get<std::string>();
      a.io(t.events[kind]);
    }
  }
  a.io(t.last_position);
}

template <typename Archive>
void point_fields(Archive& a, convoy::TrackPoint& p) {
  a.io(p.time_s);
  a.io(p.position);
  a.io(p.speed_mps);
  a.io(p.z);  // version 3: the bumper gap needs the whole pose
  a.io(p.orientation);
}

template <typename Archive>
void loss_fields(Archive& a, MemberLoss& l) {
  a.io(l.member);
  a.io(l.frame);
  a.io(l.time_s);
}

// A list: its length, then each element's fields.
template <typename Archive, typename T, typename F>
void list_io(Archive& a, std::vector<T>& list, F&& fields) {
  std::uint64_t n = list.size();
  a.io(n);
  if constexpr (std::is_same_v<Archive, core::StateReader>) list.assign(n, T{});
  for (auto& x : list) fields(a, x);
}

// A map by name: its size, then each key and the value's fields (loading replaces the map).
template <typename Archive, typename V, typename F>
void map_io(Archive& a, std::map<std::string, V>& map, F&& fields) {
  std::uint64_t n = map.size();
  a.io(n);
  if constexpr (std::is_same_v<Archive, core::StateWriter>) {
    for (auto& [key, value] : map) {
      a.io(key);
      fields(value);
    }
  } else {
    map.clear();
    for (std::uint64_t k = 0; k < n; ++k) fields(map[a.template get<std::string>()]);
  }
}

}  // namespace

void RecorderAgent::save_state(core::StateWriter& w) {
  if (!failure_.empty()) throw WriteError("no checkpoint of a failed recorder: " + failure_);
  w.begin("recorder", 4);
  for (CsvFile* f : files()) {
    if (f && f->has_pending()) {
      throw std::logic_error(f->path().string() + ": rows not committed at a checkpoint");
    }
    w.io(f != nullptr);
    if (f) w.io(f->size());
  }
  map_io(w, totals_, [&](VehicleTotals& t) { totals_fields(w, t); });
  map_io(w, tracks_,
         [&](convoy::Track& track) { list_io(w, track, point_fields<core::StateWriter>); });
  list_io(w, losses_, loss_fields<core::StateWriter>);
  w.io(terrain_bytes_);
  w.io(terrain_vertices_);
  w.io(terrain_max_frame_bytes_);
  w.io(last_frame_);
  w.io(pending_frame_);
  w.io(soil_ != nullptr);
  if (soil_) soil_->save_state(w);
  if (routing_) {  // routing is the scenario's (fingerprinted)
    soil_boxes_.save_state(w);
    w.io(static_cast<std::uint64_t>(routed_bytes_.size()));
    for (const auto& [id, bytes] : routed_bytes_) {
      w.io(id);
      w.io(bytes);
    }
  }
  std::vector<std::int32_t> changed;  // (j, i) pairs, in order
  for (const auto& [j, i] : changed_vertices_) changed.insert(changed.end(), {j, i});
  w.io(changed);
  w.end();
}

void RecorderAgent::load_state(core::StateReader& r) {
  // Version 3 (before radar.csv) lists one file fewer: the last, radar.csv, is absent.
  const auto version = r.begin("recorder", 4, 3);
  const auto files_now = files();
  for (std::size_t k = 0; k < files_now.size(); ++k) {
    CsvFile* f = files_now[k];
    const bool has = version >= 4 || k + 1 < files_now.size() ? r.get<bool>() : false;
    if (has != (f != nullptr)) {
      r.fail(std::string("the checkpointed recorder ") + (has ? "wrote" : "did not write") +
             " a CSV file this scenario " + (has ? "does not have" : "has"));
    }
    if (!f) continue;
    const auto size = r.get<std::uint64_t>();
    try {
      f->cut_to(size);
    } catch (const WriteError& e) {
      r.fail(e.what());
    }
  }
  map_io(r, totals_, [&](VehicleTotals& t) { totals_fields(r, t); });
  map_io(r, tracks_,
         [&](convoy::Track& track) { list_io(r, track, point_fields<core::StateReader>); });
  list_io(r, losses_, loss_fields<core::StateReader>);
  r.io(terrain_bytes_);
  r.io(terrain_vertices_);
  r.io(terrain_max_frame_bytes_);
  r.io(last_frame_);
  r.io(pending_frame_);
  if (r.get<bool>() != (soil_ != nullptr)) r.fail("the soil copy does not match the terrain");
  if (soil_) soil_->load_state(r);
  if (routing_) {
    soil_boxes_.load_state(r);
    routed_bytes_.clear();
    for (auto n = r.get<std::uint64_t>(); n > 0; --n) {
      auto id = r.get<std::string>();
      r.io(routed_bytes_[id]);
    }
  }
  std::vector<std::int32_t> changed;
  r.io(changed);
  if (changed.size() % 2 != 0) r.fail("changed soil vertices: an odd number of indices");
  changed_vertices_.clear();
  for (std::size_t k = 0; k < changed.size(); k += 2) changed_vertices_.emplace(changed[k], changed[k + 1]);
  r.end();
}

}  // namespace syndds::record
