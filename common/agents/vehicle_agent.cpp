#include "agents/vehicle_agent.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "agents/sensor_messages.hpp"
#include "core/error.hpp"
#include "protocol/contact_bodies.hpp"
#include "protocol/vertex_codec.hpp"
#include "vehicle/bicycle_model.hpp"
#include "vehicle/ode_vehicle.hpp"

namespace syndds::agents {

std::unique_ptr<vehicle::VehicleModel> make_vehicle_model(const scenario::Scenario& s,
                                                          const scenario::VehicleConfig& config,
                                                          std::shared_ptr<scm::ScmTerrain> scm) {
  std::shared_ptr<const terrain::TerrainSurface> terrain =
      scm ? std::shared_ptr<const terrain::TerrainSurface>(scm) : scenario::make_terrain(s.terrain);
  if (config.dynamics == "reduced") {
    return std::make_unique<vehicle::BicycleModel>(config.params, config.start, std::move(terrain));
  }
  if (config.dynamics == "full") {
    return std::make_unique<vehicle::OdeVehicleModel>(config.params, config.start,
                                                      std::move(terrain), s.obstacles, scm);
  }
  throw ConfigError("vehicle '" + config.id + "': unknown dynamics '" + config.dynamics + "'");
}

std::uint32_t member_rank(const scenario::Scenario& s, const std::string& member_id) {
  const auto members = s.member_ids();
  const auto it = std::find(members.begin(), members.end(), member_id);
  return static_cast<std::uint32_t>(it - members.begin());
}

VehicleAgent::VehicleAgent(const scenario::Scenario& scenario,
                           const scenario::VehicleConfig& vehicle)
    : vehicle_id_(vehicle.id),
      member_id_(scenario::vehicle_member(vehicle.id)),
      heartbeat_s_(scenario.time.heartbeat_s),
      step_s_(scenario.time.step_s),
      steps_per_frame_(scenario.time.steps_per_frame()) {
  if (scenario.terrain.deformable()) {
    soil_ = std::make_shared<scm::ScmTerrain>(scenario.terrain.scm);
    rank_ = member_rank(scenario, member_id_);
    soil_->set_source_id(rank_);
    spacing_m_ = scenario.terrain.scm.grid.spacing_m;
    // With routing no vehicle holds the whole soil: the recorder keeps it and writes snapshots.
    const bool routing = scenario.terrain.scm.routing;
    snapshot_provider_ = vehicle.id == scenario.vehicles.front().id && !routing;
    if (routing) subscription_.emplace(scenario.terrain.scm.interest_radius_m);
  }
  model_ = make_vehicle_model(scenario, vehicle, soil_);
  footprint_ = vehicle::footprint_of(vehicle.params);
  for (const auto& v : scenario.vehicles) {
    vehicle_params_[v.id] = std::make_shared<const vehicle::VehicleParams>(v.params);
  }
  if (vehicle.controller.is_builtin()) controller_ = scenario::controller_member(vehicle.id);
  if (vehicle.controller.type == "external") controller_ = scenario::external_member(vehicle.id);
  if (vehicle.has_interoceptive_sensors()) {
    sensors_ = std::make_unique<sensors::VehicleSensors>(vehicle.sensors->rig, vehicle.id,
                                                         scenario.seed, step_s_,
                                                         scenario.time.heartbeat_s,
                                                         sensors::SensorSet::interoceptive);
  }
  if (vehicle.v2v) {
    v2v_ = std::make_unique<convoy::V2VBroadcaster>(*vehicle.v2v, vehicle_id_, member_id_,
                                                    vehicle.params.wheels.radius_m,
                                                    scenario.seed);
  }
}

std::vector<proto::Subscription> VehicleAgent::subscriptions() const {
  std::vector<proto::Subscription> subs = {{proto::Topic::driver_command, vehicle_id_}};
  if (subscription_) {
    subs.push_back({proto::Topic::terrain_patch, vehicle_id_});
    subs.push_back({proto::Topic::soil_interest, ""});
  } else if (soil_) {
    subs.push_back({proto::Topic::terrain_deformation, ""});
  }
  return subs;
}

std::vector<proto::Topic> VehicleAgent::publications() const {
  std::vector<proto::Topic> pubs = {proto::Topic::vehicle_state, proto::Topic::collision_event,
                                    proto::Topic::vehicle_event};
  if (soil_) pubs.push_back(proto::Topic::terrain_deformation);
  if (subscription_) {
    pubs.insert(pubs.end(), {proto::Topic::soil_interest, proto::Topic::terrain_patch});
  }
  if (snapshot_provider_) pubs.push_back(proto::Topic::terrain_snapshot);
  if (sensors_) {
    pubs.insert(pubs.end(), {proto::Topic::gps_fix, proto::Topic::imu, proto::Topic::magnetometer,
                             proto::Topic::wheel_speeds});
  }
  if (v2v_) pubs.push_back(proto::Topic::v2v_message);
  return pubs;
}

void VehicleAgent::log_terrain_hashes(const std::string& file) {
  if (subscription_) {
    throw ConfigError("the terrain hash log needs the whole soil, which a vehicle does not "
                      "receive with terrain.scm.routing");
  }
  try {
    hash_log_ = std::make_unique<record::OutputFile>(file);
  } catch (const record::WriteError& e) {
    throw ConfigError(std::string(e.what()) + " (terrain hash log)");
  }
}

void VehicleAgent::note_departed(const proto::FrameContext& ctx, proto::FrameSamples& outputs) {
  if (controller_lost_ || controller_.empty()) return;
  if (std::find(ctx.departed.begin(), ctx.departed.end(), controller_) == ctx.departed.end()) {
    return;
  }
  // Nobody drives any more: brake to a stop, wheels as they are, rather than drive on blind.
  controller_lost_ = true;
  const vehicle::DriverInputs last = model_->snapshot().inputs;
  model_->set_inputs({last.steering, 0.0, 1.0});
  spdlog::warn("{}: {} was lost in frame {}; braking to a stop", member_id_, controller_,
               ctx.frame);
  outputs.vehicle_events.push_back({vehicle_id_, member_id_, ctx.frame, ctx.sim_time_s,
                                    "controller_lost",
                                    controller_ + " was lost; braking to a stop, steering held"});
}

void VehicleAgent::finish(const proto::RunEnd&, const proto::FrameSamples& final_inputs) {
  if (subscription_) {
    for (const auto& d : final_inputs.terrain_patches) {
      routed_bytes_ += proto::packed_size(d.vertices);
    }
    spdlog::info("{}: soil routing: received {} bytes of records addressed to it ({} records of "
                 "the others' frames, {} records of the recorder's soil as its box moved)",
                 member_id_, routed_bytes_, routed_live_, routed_replayed_);
  }
  if (max_deferred_ > 0) {
    spdlog::info("{}: interest management held up to {} vertices of other vehicles' ruts aside "
                 "(merged when this vehicle came within {:g} m)",
                 member_id_, max_deferred_, soil_->params().interest_radius_m);
  }
}

void VehicleAgent::note_rejected(const std::vector<proto::RejectedSample>& rejected) {
  for (const auto& r : rejected) {
    if (r.topic == proto::Topic::driver_command && r.key == vehicle_id_) intrusions_.push_back(r);
  }
}

void VehicleAgent::step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                        proto::FrameSamples& outputs) {
  // Commands the transport refused (a writer that is not the declared controller's
  // participant) since the last frame: each is an event, never an input.
  for (const auto& r : intrusions_) {
    ++rejected_;
    outputs.vehicle_events.push_back({vehicle_id_, member_id_, ctx.frame, ctx.sim_time_s,
                                      "command_rejected",
                                      "claimed " + r.source + " stamped frame " +
                                          std::to_string(r.frame) + ": " + r.reason});
  }
  intrusions_.clear();
  if (soil_) merge_soil(ctx, inputs);
  // The newest valid command stamped k-1 (several writers: the last in canonical order wins).
  for (const auto& cmd : inputs.driver_commands) {
    const std::string error = proto::validate_command(cmd);
    if (!error.empty()) {
      ++rejected_;
      spdlog::error("{}: rejected driver_command from {} stamped frame {}: {}", member_id_,
                    cmd.source, cmd.frame, error);
      outputs.vehicle_events.push_back({vehicle_id_, member_id_, ctx.frame, ctx.sim_time_s,
                                        "command_rejected",
                                        "from " + cmd.source + " stamped frame " +
                                            std::to_string(cmd.frame) + ": " + error});
      continue;
    }
    model_->set_inputs({cmd.steering, cmd.throttle, cmd.braking});
  }
  note_departed(ctx, outputs);
  if (ctx.frame > 0) {
    set_peers(inputs.contact_bodies);
    for (std::int64_t i = 0; i < steps_per_frame_; ++i) {
      model_->advance(step_s_);
      // Interoceptive sensors sample the dynamics at every step (their rate and lag are theirs).
      if (sensors_) sensors_->update_dynamics(model_->snapshot());
    }
  }
  if (sensors_) {
    const auto batch = sensors_->take_interoceptive(ctx.sim_time_s);
    append_messages(batch, vehicle_id_, member_id_, ctx.frame, outputs);
    if (v2v_) {
      v2v_->observe(batch);
      for (auto& m : v2v_->step(ctx.frame, ctx.sim_time_s)) outputs.v2v_messages.push_back(m);
    }
  }
  const vehicle::VehicleSnapshot snapshot = model_->snapshot();
  outputs.vehicle_states.push_back(state_message(snapshot, ctx.frame, ctx.sim_time_s));
  outputs.contact_bodies.push_back(body_message(snapshot));
  if (soil_) publish_soil(ctx, outputs);
  for (const auto& c : model_->take_collisions()) {
    proto::CollisionEventMsg e;
    e.vehicle_id = vehicle_id_;
    e.source = member_id_;
    e.frame = ctx.frame;
    e.sim_time_s = ctx.sim_time_s;
    e.obstacle_id = c.obstacle_id;
    e.impulse_ns = c.impulse_ns;
    e.position = c.position;
    e.other_vehicle_id = c.other_vehicle;
    e.relative_speed_mps = c.relative_speed_mps;
    outputs.collision_events.push_back(std::move(e));
  }
}

void VehicleAgent::merge_soil(const proto::FrameContext& ctx, const proto::FrameSamples& inputs) {
  const double radius = soil_->params().interest_radius_m;
  const Vec3& p = model_->snapshot().pose.position;
  if (subscription_) {
    // Soil routing: the boxes the others published in frame k-1 (used from this frame on), the
    // recorder's state of the tiles this vehicle's box gained in frame k-2, then the check that
    // the writers of frame k-1 covered the interest square.
    peer_boxes_.update(inputs.soil_interests, vehicle_id_);
    bool replayed = false;
    for (const auto& d : inputs.terrain_patches) {
      routed_bytes_ += proto::packed_size(d.vertices);
      if (d.replay && d.source != scenario::kRecorderMember) {
        throw ProtocolError(member_id_ + ": a terrain_patch replay from " + d.source +
                            "; only the recorder keeps the whole soil");
      }
      replayed = replayed || d.replay;
    }
    const auto due = subscription_->begin_frame(ctx.frame);
    if (replayed && due.empty()) {
      throw ProtocolError(member_id_ + ": the recorder's tiles arrived in frame " +
                          std::to_string(ctx.frame) + ", two frames after no change of its box");
    }
    for (const auto& change : due) {
      std::vector<scm::VertexChange> state;
      for (const auto& patch : inputs.terrain_patches) {
        if (!patch.replay) continue;
        const auto records = from_messages(patch.vertices);
        state.insert(state.end(), records.begin(), records.end());
      }
      routed_replayed_ += state.size();
      soil_->load_added_tiles(change.now, change.before, state);
      soil_->drop_tiles_outside(change.now);
    }
    subscription_->check_covers(vehicle_id_, ctx.frame,
                                soil_->interest_box(p.x(), p.y(), radius));
  }
  // Interest management: only the soil around this vehicle is merged now (it cannot reach
  // farther within a frame); the rest waits, exactly, until the vehicle comes near.
  if (radius > 0.0) soil_->set_interest_region(p.x(), p.y(), radius);
  // The other vehicles' deformations of frame k-1, merged by the SCM rule (order-free).
  if (subscription_) {
    for (const auto& d : inputs.terrain_patches) {
      if (d.replay) continue;
      soil_->apply_remote_changes(d.source_index, from_messages(d.vertices));
      routed_live_ += d.vertices.size();
    }
  } else {
    for (const auto& d : inputs.terrain_deformations) {
      if (d.vehicle_id == vehicle_id_) continue;  // our own, applied in place already
      soil_->apply_remote_changes(d.source_index, from_messages(d.vertices));
    }
  }
  max_deferred_ = std::max(max_deferred_, soil_->deferred_vertices());
  if (hash_log_ && ctx.frame > 0) {
    soil_->flush_deferred();  // the hash covers the whole grid
    hash_log_->write(fmt::format("{} {:016x}\n", ctx.frame - 1, soil_->grid_hash()));
  }
}

void VehicleAgent::publish_soil(const proto::FrameContext& ctx, proto::FrameSamples& outputs) {
  // Every frame opens a new merge window; only non-empty lists travel.
  const auto changes = soil_->take_local_changes();
  if (!changes.empty()) {
    proto::TerrainDeformationMsg d;
    d.vehicle_id = vehicle_id_;
    d.source = member_id_;
    d.frame = ctx.frame;
    d.source_index = rank_;
    d.spacing_m = spacing_m_;
    d.vertices.reserve(changes.size());
    for (const auto& c : changes) d.vertices.push_back(to_message(c));
    if (subscription_) {
      // Routing: to each vehicle, the changes inside the box it published by frame k-1.
      for (const auto& [id, box] : peer_boxes_.boxes()) {
        auto in_box = records_in(d.vertices, box);
        if (in_box.empty()) continue;
        outputs.terrain_patches.push_back(
            {id, member_id_, ctx.frame, rank_, spacing_m_, false, std::move(in_box)});
      }
    }
    outputs.terrain_deformations.push_back(std::move(d));
  }
  if (subscription_) {
    const Vec3& p = model_->snapshot().pose.position;
    if (const auto box = subscription_->renew(ctx.frame, *soil_, p.x(), p.y())) {
      outputs.soil_interests.push_back(
          {vehicle_id_, member_id_, ctx.frame, box->i_lo, box->i_hi, box->j_lo, box->j_hi});
    }
  }
  if (snapshot_provider_ && !ctx.joiners.empty()) {
    // Late joiners start from this copy as it is now (own changes of this frame included;
    // they apply the others' changes of this frame themselves, like everyone else).
    soil_->flush_deferred();  // a late joiner gets the whole soil
    const scm::ScmSnapshot snap = soil_->snapshot();
    proto::TerrainSnapshotMsg m;
    m.vehicle_id = vehicle_id_;
    m.source = member_id_;
    m.frame = ctx.frame;
    m.spacing_m = snap.spacing_m;
    m.vertices.reserve(snap.vertices.size());
    for (const auto& v : snap.vertices) m.vertices.push_back(to_message(v));
    outputs.terrain_snapshots.push_back(std::move(m));
  }
}

proto::VehicleBodyMsg VehicleAgent::body_message(const vehicle::VehicleSnapshot& s) const {
  proto::VehicleBodyMsg b;
  b.vehicle_id = vehicle_id_;
  b.pose = s.pose;
  b.linear_velocity = s.linear_velocity;
  b.angular_velocity = s.angular_velocity;
  for (const auto& w : s.wheels) b.wheels.push_back(w.pose);
  b.footprint_offset_m = footprint_.offset_m;
  b.footprint_half_length_m = footprint_.half_length_m;
  b.footprint_half_width_m = footprint_.half_width_m;
  return b;
}

void VehicleAgent::set_peers(const std::vector<proto::VehicleBodyMsg>& bodies) {
  // The bodies hold ours only when another vehicle is near; ours as of frame k-1 is our state
  // now, bit for bit.
  std::vector<vehicle::PeerVehicle> peers;
  if (!bodies.empty()) {
    const proto::VehicleBodyMsg own = body_message(model_->snapshot());
    for (const auto& b : bodies) {
      if (b.vehicle_id == vehicle_id_ || !proto::within_reach(own, b, heartbeat_s_)) continue;
      const auto it = vehicle_params_.find(b.vehicle_id);
      if (it == vehicle_params_.end()) {
        throw ProtocolError(member_id_ + ": a contact body of vehicle '" + b.vehicle_id +
                            "', which this scenario does not have");
      }
      vehicle::PeerVehicle p;
      p.id = b.vehicle_id;
      p.params = it->second;
      p.pose = b.pose;
      p.linear_velocity = b.linear_velocity;
      p.angular_velocity = b.angular_velocity;
      p.wheels = b.wheels;
      peers.push_back(std::move(p));
    }
  }
  model_->set_peers(std::move(peers));
}

proto::VehicleStateMsg VehicleAgent::state_message(const vehicle::VehicleSnapshot& s,
                                                   std::int64_t frame, double sim_time_s) const {
  proto::VehicleStateMsg m;
  m.vehicle_id = vehicle_id_;
  m.source = member_id_;
  m.frame = frame;
  m.sim_time_s = sim_time_s;
  m.pose = s.pose;
  m.linear_velocity = s.linear_velocity;
  m.angular_velocity = s.angular_velocity;
  m.linear_acceleration = s.linear_acceleration;
  m.angular_acceleration = s.angular_acceleration;
  for (const auto& w : s.wheels) {
    m.wheels.push_back({w.pose, w.spin_rad_s, w.steer_angle_rad, w.vertical_load_n});
  }
  m.steering = s.inputs.steering;
  m.throttle = s.inputs.throttle;
  m.braking = s.inputs.braking;
  m.gear = s.gear;
  m.engine_speed_rpm = s.engine_speed_rpm;
  return m;
}

void VehicleAgent::save_state(core::StateWriter& w) {
  w.begin("vehicle_agent", 1);
  w.io(rejected_);
  w.io(static_cast<std::uint64_t>(max_deferred_));
  w.io(controller_lost_);
  model_->save_state(w);
  w.io(soil_ != nullptr);
  if (soil_) soil_->save_state(w);
  if (subscription_) {  // routing is the scenario's (fingerprinted): no flag needed
    subscription_->save_state(w);
    peer_boxes_.save_state(w);
  }
  w.io(sensors_ != nullptr);
  if (sensors_) sensors_->save_state(w);
  w.io(v2v_ != nullptr);
  if (v2v_) v2v_->save_state(w);
  w.end();
}

void VehicleAgent::load_state(core::StateReader& r) {
  r.begin("vehicle_agent", 1);
  r.io(rejected_);
  max_deferred_ = static_cast<std::size_t>(r.get<std::uint64_t>());
  r.io(controller_lost_);
  model_->load_state(r);
  const auto expect = [&](bool has, const char* what) {
    if (r.get<bool>() != has) {
      r.fail(std::string("the checkpointed vehicle ") + (has ? "had no " : "had a ") + what +
             "; this scenario's " + (has ? "has one" : "has none"));
    }
    return has;
  };
  if (expect(soil_ != nullptr, "soil copy")) soil_->load_state(r);
  if (subscription_) {
    subscription_->load_state(r);
    peer_boxes_.load_state(r);
  }
  if (expect(sensors_ != nullptr, "sensors")) sensors_->load_state(r);
  if (expect(v2v_ != nullptr, "V2V broadcaster")) v2v_->load_state(r);
  r.end();
}

}  // namespace syndds::agents
