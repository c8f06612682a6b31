#include "agents/sensor_agent.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>

#include "agents/scm_messages.hpp"
#include "agents/sensor_messages.hpp"
#include "core/error.hpp"

namespace syndds::agents {
namespace fs = std::filesystem;
namespace {

constexpr double kRenderSpacingM = 0.1;    // untouched SCM soil is drawn at about this spacing
constexpr double kFlatSpacingM = 2.0;      // a flat plane needs no resolution
constexpr double kWorldMarginM = 60.0;     // rendered ground beyond the paths and obstacles

// The area worth rendering: every path, start and obstacle, plus a margin.
void world_bounds(const scenario::Scenario& s, double& x0, double& x1, double& y0, double& y1) {
  x0 = y0 = std::numeric_limits<double>::infinity();
  x1 = y1 = -x0;
  auto grow = [&](double x, double y) {
    x0 = std::min(x0, x);
    x1 = std::max(x1, x);
    y0 = std::min(y0, y);
    y1 = std::max(y1, y);
  };
  for (const auto& v : s.vehicles) {
    grow(v.start.position.x(), v.start.position.y());
    for (const auto& w : v.controller.waypoints) grow(w.x(), w.y());
  }
  for (const auto& o : s.obstacles) grow(o.pose.position.x(), o.pose.position.y());
  x0 -= kWorldMarginM;
  y0 -= kWorldMarginM;
  x1 += kWorldMarginM;
  y1 += kWorldMarginM;
}

// Snow-like soft soil renders white, firmer soils silt-brown, rigid ground neutral grey or the
// scenario's terrain.colour.
sensors::TerrainLook look_of(const scenario::TerrainConfig& t) {
  if (t.type == "scm") {
    return sensors::terrain_look(t.scm.soil.bekker_kphi < 1.0e6 ? "snow" : "silt");
  }
  sensors::TerrainLook look = sensors::terrain_look("rigid");
  if (t.colour) {
    look.colour = {static_cast<float>((*t.colour)[0]), static_cast<float>((*t.colour)[1]),
                   static_cast<float>((*t.colour)[2])};
  }
  return look;
}

}  // namespace

SensorAgent::SensorAgent(const scenario::Scenario& s, const scenario::VehicleConfig& vehicle,
                         SensorAgentOptions options)
    : vehicle_id_(vehicle.id),
      member_id_(scenario::sensor_member(vehicle.id)),
      deformable_(s.terrain.deformable()),
      config_(*vehicle.sensors),
      options_(std::move(options)) {
  scene_ = std::make_unique<sensors::Scene>(config_.rig.scene);
  if (deformable_) {
    soil_ = std::make_unique<scm::ScmTerrain>(s.terrain.scm);
    soil_->set_source_id(static_cast<std::uint32_t>(s.member_ids().size()));  // never wins a tie
  }
  const auto surface = scenario::make_terrain(s.terrain);
  if (s.terrain.type == "scm") {
    const auto& g = s.terrain.scm.grid;
    // The scene holds the soil's own grid: a tile is drawn at the soil's spacing once a
    // vertex in it deforms (ruts without steps), at about kRenderSpacingM until then.
    const int coarse = std::max(1, static_cast<int>(std::lround(kRenderSpacingM / g.spacing_m)));
    // Kept to draw the soil afresh when a rollback (on_member_loss: recover) takes back ruts
    // made after the checkpoint.
    reset_terrain_ = [this, surface, g, coarse, look = look_of(s.terrain)] {
      scene_->set_terrain(sensors::sample_terrain(*surface, g.spacing_m, g.x_min_m, g.x_max_m,
                                                  g.y_min_m, g.y_max_m),
                          look, coarse);
    };
    reset_terrain_();
  } else if (s.terrain.type == "heightmap") {
    const auto& h = s.terrain.heightmap;
    const double spacing = std::max(0.1, h.size_x_m / 1024.0);
    scene_->set_terrain(sensors::sample_terrain(*surface, spacing,
                                                h.centre_m.x() - h.size_x_m / 2,
                                                h.centre_m.x() + h.size_x_m / 2,
                                                h.centre_m.y() - h.size_y_m / 2,
                                                h.centre_m.y() + h.size_y_m / 2),
                        look_of(s.terrain));
  } else {
    double x0, x1, y0, y1;
    world_bounds(s, x0, x1, y0, y1);
    scene_->set_terrain(sensors::sample_terrain(*surface, kFlatSpacingM, x0, x1, y0, y1),
                        look_of(s.terrain));
  }
  scene_->add_obstacles(s.obstacles);
  for (std::size_t i = 0; i < s.vehicles.size(); ++i) {
    const auto& v = s.vehicles[i];
    scene_->add_vehicle(v.id, sensors::vehicle_shape(v.params, sensors::vehicle_palette(i)));
    scene_->set_vehicle_pose(v.id, v.start, {});
    poses_[v.id] = {v.start, {}, Vec3::Zero(), Vec3::Zero()};
  }
  scene_->commit();
  sensors_ = std::make_unique<sensors::VehicleSensors>(config_.rig, vehicle_id_, s.seed,
                                                       s.time.step_s, s.time.heartbeat_s);
  if (config_.save_images || config_.video) {
    const fs::path dir = fs::path(options_.output_dir) / vehicle_id_;
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw ConfigError(dir.string() + ": cannot create sensor output directory");
    index_ = std::make_unique<record::CsvFile>(
        dir / "frames.csv",
        std::vector<std::string>{"sensor", "sequence", "time_s", "available_s", "x", "y", "z",
                                 "qw", "qx", "qy", "qz", "file"},
        options_.resume ? record::OutputFile::Open::resume : record::OutputFile::Open::create);
  }
}

SensorAgent::~SensorAgent() = default;

std::vector<proto::Subscription> SensorAgent::subscriptions() const {
  std::vector<proto::Subscription> subs = {{proto::Topic::vehicle_state, ""}};
  if (deformable_) {
    subs.push_back({proto::Topic::terrain_deformation, ""});
    subs.push_back({proto::Topic::terrain_snapshot, ""});
  }
  return subs;
}

std::vector<proto::Topic> SensorAgent::publications() const {
  return {proto::Topic::image, proto::Topic::point_cloud, proto::Topic::radar};
}

void SensorAgent::update_world(const proto::FrameSamples& inputs) {
  for (const auto& st : inputs.vehicle_states) {
    if (!scene_->has_vehicle(st.vehicle_id)) continue;
    std::vector<Pose> wheels;
    wheels.reserve(st.wheels.size());
    for (const auto& w : st.wheels) wheels.push_back(w.pose);
    scene_->set_vehicle_pose(st.vehicle_id, st.pose, wheels);
    scene_->set_vehicle_velocity(st.vehicle_id, st.linear_velocity, st.angular_velocity);
    poses_[st.vehicle_id] = {st.pose, std::move(wheels), st.linear_velocity, st.angular_velocity};
  }
  if (soil_) {
    // The soil copy merges every list by the SCM rule; the scene shows the merged heights.
    std::vector<sensors::HeightUpdate> updates;
    for (const auto& snap : inputs.terrain_snapshots) {  // a late joiner's starting point
      soil_->load_snapshot({snap.spacing_m, from_messages(snap.vertices)});
      for (const auto& v : snap.vertices) render_vertex(v.i, v.j, updates);
    }
    for (const auto& d : inputs.terrain_deformations) {
      soil_->apply_remote_changes(d.source_index, from_messages(d.vertices));
    }
    for (const auto& d : inputs.terrain_deformations) {
      for (const auto& v : d.vertices) render_vertex(v.i, v.j, updates);
    }
    soil_->take_local_changes();  // opens the merge window of the next frame's lists
    if (!updates.empty()) scene_->update_terrain_world(updates);
  }
  if (!options_.commit_only_to_render) scene_->commit();
}

void SensorAgent::render_vertex(std::int32_t i, std::int32_t j,
                                std::vector<sensors::HeightUpdate>& out) const {
  const auto v = soil_->vertex(i, j);
  if (v) out.push_back({i, j, v->level_m});
}

void SensorAgent::remove_departed(const std::vector<std::string>& departed) {
  const std::string prefix = scenario::vehicle_member("");
  bool removed = false;
  for (const auto& member : departed) {
    if (member.rfind(prefix, 0) != 0) continue;
    const std::string id = member.substr(prefix.size());
    // Our own vehicle is never drawn for our own sensors, and they still ride where it stopped.
    if (id == vehicle_id_ || !scene_->has_vehicle(id)) continue;
    scene_->remove_vehicle(id);
    poses_.erase(id);
    removed = true;
    spdlog::info("{}: vehicle '{}' was lost; removed from the scene", member_id_, id);
  }
  if (removed) scene_->commit();
}

void SensorAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                       proto::FrameSamples& outputs) {
  stepped_ = true;
  remove_departed(ctx.departed);
  if (ctx.frame == 0) {
    if (soil_) soil_->take_local_changes();  // the merge window of frame 0's lists
    return;  // nothing stamped -1: the world is rendered from frame 1 on
  }
  // The world as it was at the end of frame k-1.
  const double t = static_cast<double>(ctx.frame - 1) * ctx.heartbeat_s;
  update_world(inputs);
  if (options_.commit_only_to_render && !scene_->committed() && sensors_->may_render(t)) {
    scene_->commit();
  }
  sensors_->update_rendered(*scene_, t);
  const sensors::RenderedBatch batch = sensors_->take_rendered(t);
  frames_rendered_ += batch.camera.size();
  if (index_) save(batch);
  append_messages(batch, vehicle_id_, member_id_, ctx.frame, outputs);
}

void SensorAgent::save(const sensors::RenderedBatch& batch) {
  const fs::path dir = fs::path(options_.output_dir) / vehicle_id_;
  for (const auto& f : batch.camera) {
    std::string file;
    if (config_.save_images) {
      file = fmt::format("{}_{:06d}.png", f.sensor_id, f.stamp.sequence);
      sensors::write_png((dir / file).string(), f.image);
    }
    if (config_.video) {
      auto& video = videos_[f.sensor_id];
      if (!video) {
        video = open_video(f.sensor_id, f.image.width, f.image.height,
                           sensors::VideoWriter::Open::create);
      }
      video->write(f.image);
    }
    const auto& p = f.pose.position;
    const auto& q = f.pose.orientation;
    index_->row(f.sensor_id, f.stamp.sequence, f.stamp.time_s, f.stamp.available_s, p.x(), p.y(),
                p.z(), q.w(), q.x(), q.y(), q.z(), file);
  }
  index_->commit();
}

std::unique_ptr<sensors::VideoWriter> SensorAgent::open_video(
    const std::string& id, int width, int height, sensors::VideoWriter::Open open) const {
  double fps = 30.0;
  for (const auto& c : config_.rig.cameras) {
    if (c.id == id) fps = c.rate_hz;
  }
  const fs::path file = fs::path(options_.output_dir) / vehicle_id_ / (id + ".avi");
  return std::make_unique<sensors::VideoWriter>(file.string(), fps, width, height, open);
}

void SensorAgent::finish(const proto::RunEnd& end, const proto::FrameSamples& final_inputs) {
  if (soil_ && !final_inputs.empty()) update_world(final_inputs);
  for (auto& [id, video] : videos_) video->close();
  spdlog::info("{}: rendered {} camera frames", member_id_, frames_rendered_);
  if (soil_) spdlog::info("{}: terrain grid hash {:016x}", member_id_, soil_->grid_hash());
}

void SensorAgent::save_state(core::StateWriter& w) {
  w.begin("sensor_agent", 3);
  w.io(frames_rendered_);
  w.io(static_cast<std::uint64_t>(poses_.size()));
  for (const auto& [id, view] : poses_) {
    w.io(id);
    w.io(view.chassis.position);
    w.io(view.chassis.orientation);
    w.io(static_cast<std::uint64_t>(view.wheels.size()));
    for (const auto& p : view.wheels) {
      w.io(p.position);
      w.io(p.orientation);
    }
    w.io(view.linear_velocity);
    w.io(view.angular_velocity);
  }
  sensors_->save_state(w);
  w.io(soil_ != nullptr);
  if (soil_) soil_->save_state(w);
  w.io(index_ != nullptr);
  if (index_) w.io(index_->size());
  w.io(static_cast<std::uint64_t>(videos_.size()));
  for (const auto& [id, video] : videos_) {
    w.io(id);
    video->save_state(w);
  }
  w.end();
}

void SensorAgent::load_videos(core::StateReader& r, std::uint64_t count) {
  std::set<std::string> restored;
  for (std::uint64_t k = 0; k < count; ++k) {
    const auto id = r.get<std::string>();
    const sensors::CameraConfig* camera = nullptr;
    for (const auto& c : config_.rig.cameras) {
      if (c.id == id) camera = &c;
    }
    if (!config_.video || !camera) {
      r.fail("the checkpoint has a video of camera '" + id + "', this rig writes none");
    }
    auto& video = videos_[id];
    try {
      if (!video) {
        video = open_video(id, camera->intrinsics.width, camera->intrinsics.height,
                           sensors::VideoWriter::Open::resume);
      }
    } catch (const std::exception& e) {
      videos_.erase(id);
      r.fail(e.what());
    }
    video->load_state(r);
    restored.insert(id);
  }
  // A video begun after the checkpoint is no more: an undisturbed run had no file yet.
  for (const auto& c : config_.rig.cameras) {
    if (!config_.video || restored.contains(c.id)) continue;
    try {
      if (auto v = videos_.find(c.id); v != videos_.end()) {
        v->second->discard();
        videos_.erase(v);
      } else {
        fs::remove(fs::path(options_.output_dir) / vehicle_id_ / (c.id + ".avi"));
      }
    } catch (const std::exception& e) {
      r.fail(e.what());
    }
  }
}

void SensorAgent::load_state(core::StateReader& r) {
  // Version 1 (before videos could be checkpointed) holds no videos, version 2 (before
  // radars) no velocities.
  const auto version = r.begin("sensor_agent", 3, 1);
  r.io(frames_rendered_);
  std::map<std::string, VehicleView> poses;
  const auto n = r.get<std::uint64_t>();
  for (std::uint64_t k = 0; k < n; ++k) {
    const auto id = r.get<std::string>();
    if (!scene_->has_vehicle(id)) r.fail("vehicle '" + id + "' is not in this scenario's scene");
    auto& view = poses[id];
    r.io(view.chassis.position);
    r.io(view.chassis.orientation);
    view.wheels.resize(static_cast<std::size_t>(r.get<std::uint64_t>()));
    for (auto& p : view.wheels) {
      r.io(p.position);
      r.io(p.orientation);
    }
    if (version >= 3) {
      r.io(view.linear_velocity);
      r.io(view.angular_velocity);
    }
  }
  sensors_->load_state(r);
  if (r.get<bool>() != (soil_ != nullptr)) r.fail("the soil copy does not match the terrain");
  if (soil_) soil_->load_state(r);
  if (r.get<bool>() != (index_ != nullptr)) r.fail("the frame index does not match the rig");
  if (index_) {
    const auto size = r.get<std::uint64_t>();
    try {
      index_->cut_to(size);
    } catch (const record::WriteError& e) {
      r.fail(e.what());
    }
  }
  load_videos(r, version >= 2 ? r.get<std::uint64_t>() : 0);
  r.end();
  // The scene as it was: vehicles removed since the start stay removed, the others where they
  // were, the terrain at the soil copy's heights.
  for (const auto& [id, view] : poses_) {
    if (!poses.contains(id)) scene_->remove_vehicle(id);
  }
  for (const auto& [id, view] : poses) {
    scene_->set_vehicle_pose(id, view.chassis, view.wheels);
    scene_->set_vehicle_velocity(id, view.linear_velocity, view.angular_velocity);
  }
  poses_ = std::move(poses);
  if (soil_) {
    if (stepped_) reset_terrain_();  // a rollback: ruts of later frames are drawn in the scene
    std::vector<sensors::HeightUpdate> updates;
    for (const auto& v : soil_->snapshot().vertices) render_vertex(v.i, v.j, updates);
    if (!updates.empty()) scene_->update_terrain_world(updates);
  }
  if (!options_.commit_only_to_render) scene_->commit();
}

void SensorAgent::set_camera_frame_filter(const sensors::CameraSensor::FrameFilter& filter) {
  for (auto& c : sensors_->cameras()) c->set_frame_filter(filter);
}

}  // namespace syndds::agents
