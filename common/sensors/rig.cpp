#include "sensors/rig.hpp"

#include <sstream>
#include <stdexcept>

#include "core/state_io.hpp"

namespace syndds::sensors {
namespace {

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// Sensors of one kind in rig order, each behind its id so a state of another rig is refused
// by name rather than read into the wrong sensor.
template <typename Sensor, typename Id>
void save_kind(core::StateWriter& w, const std::vector<Sensor>& sensors, Id&& id) {
  w.io(static_cast<std::uint64_t>(sensors.size()));
  for (const auto& s : sensors) {
    w.io(id(s));
    if constexpr (requires { s->save_state(w); }) {
      s->save_state(w);
    } else {
      s.save_state(w);
    }
  }
}

template <typename Sensor, typename Id>
void load_kind(core::StateReader& r, std::vector<Sensor>& sensors, Id&& id, const char* kind) {
  const auto n = r.get<std::uint64_t>();
  if (n != sensors.size()) {
    r.fail(std::string("the state has ") + std::to_string(n) + " " + kind + " sensors, this rig " +
           std::to_string(sensors.size()));
  }
  for (auto& s : sensors) {
    const auto saved = r.get<std::string>();
    if (saved != id(s)) {
      r.fail(std::string("the state has ") + kind + " '" + saved + "' where this rig has '" +
             id(s) + "'");
    }
    if constexpr (requires { s->load_state(r); }) {
      s->load_state(r);
    } else {
      s.load_state(r);
    }
  }
}

}  // namespace

std::uint64_t sensor_seed(std::uint64_t scenario_seed, const std::string& vehicle_id,
                          const std::string& sensor_id) {
  return derive_seed(scenario_seed, vehicle_id + "/" + sensor_id);
}

VehicleSensors::VehicleSensors(const SensorRig& rig, std::string vehicle_id,
                               std::uint64_t scenario_seed, double step_s, double heartbeat_s,
                               SensorSet set)
    : vehicle_id_(std::move(vehicle_id)) {
  const bool interoceptive = set != SensorSet::rendered;
  const bool rendered = set != SensorSet::interoceptive;
  std::string current;
  try {
    auto seed = [&](const std::string& id) {
      current = id;
      return sensor_seed(scenario_seed, vehicle_id_, id);
    };
    if (interoceptive) {
      for (const auto& c : rig.gps) gps_.emplace_back(c, rig.geodetic_origin, seed(c.id), step_s);
      for (const auto& c : rig.imus) imus_.emplace_back(c, seed(c.id), step_s);
      for (const auto& c : rig.magnetometers) magnetometers_.emplace_back(c, seed(c.id), step_s);
      for (const auto& c : rig.tachometers) tachometers_.emplace_back(c, seed(c.id), step_s);
    }
    if (rendered) {
      for (const auto& c : rig.cameras) {
        cameras_.push_back(std::make_unique<CameraSensor>(
            c, c.mode == CameraMode::fixed ? std::string() : vehicle_id_, seed(c.id),
            heartbeat_s));
      }
      for (const auto& c : rig.lidars) {
        lidars_.push_back(std::make_unique<LidarSensor>(c, vehicle_id_, seed(c.id), heartbeat_s));
      }
      for (const auto& c : rig.radars) {
        radars_.push_back(std::make_unique<RadarSensor>(c, vehicle_id_, seed(c.id), heartbeat_s));
      }
    }
  } catch (const std::invalid_argument& e) {
    throw ConfigError(rig.file + ": sensor '" + current + "' on vehicle '" + vehicle_id_ + "': " +
                      e.what() + " (step " + fmt(step_s) + " s, frame " + fmt(heartbeat_s) + " s)");
  }
}

void VehicleSensors::update_dynamics(const vehicle::VehicleSnapshot& snapshot) {
  for (auto& s : gps_) s.update(snapshot);
  for (auto& s : imus_) s.update(snapshot);
  for (auto& s : magnetometers_) s.update(snapshot);
  for (auto& s : tachometers_) s.update(snapshot);
}

void VehicleSensors::update_rendered(const Scene& scene, double time_s) {
  for (auto& c : cameras_) c->update(scene, time_s);
  for (auto& l : lidars_) l->update(scene, time_s);
  for (auto& r : radars_) r->update(scene, time_s);
}

bool VehicleSensors::may_render(double time_s) const {
  if (!lidars_.empty() || !radars_.empty()) return true;
  for (const auto& c : cameras_) {
    if (c->may_render(time_s)) return true;
  }
  return false;
}

InteroceptiveBatch VehicleSensors::take_interoceptive(double now_s) {
  InteroceptiveBatch b;
  auto append = [](auto& out, auto&& in) {
    for (auto& x : in) out.push_back(std::move(x));
  };
  for (auto& s : gps_) append(b.gps, s.take_available(now_s));
  for (auto& s : imus_) append(b.imu, s.take_available(now_s));
  for (auto& s : magnetometers_) append(b.magnetometer, s.take_available(now_s));
  for (auto& s : tachometers_) append(b.tachometer, s.take_available(now_s));
  return b;
}

RenderedBatch VehicleSensors::take_rendered(double now_s) {
  RenderedBatch b;
  for (auto& c : cameras_) {
    for (auto& f : c->take_available(now_s)) b.camera.push_back(std::move(f));
  }
  for (auto& l : lidars_) {
    for (auto& s : l->take_available(now_s)) b.lidar.push_back(std::move(s));
  }
  for (auto& r : radars_) {
    for (auto& s : r->take_available(now_s)) b.radar.push_back(std::move(s));
  }
  return b;
}

void VehicleSensors::save_state(core::StateWriter& w) const {
  w.begin("vehicle_sensors", 2);
  w.io(vehicle_id_);
  auto id = [](const auto& s) -> const std::string& { return s.config().id; };
  auto pid = [](const auto& s) -> const std::string& { return s->config().id; };
  save_kind(w, gps_, id);
  save_kind(w, imus_, id);
  save_kind(w, magnetometers_, id);
  save_kind(w, tachometers_, id);
  save_kind(w, cameras_, pid);
  save_kind(w, lidars_, pid);
  save_kind(w, radars_, pid);
  w.end();
}

void VehicleSensors::load_state(core::StateReader& r) {
  // Version 1 (before radars) holds none.
  const auto version = r.begin("vehicle_sensors", 2, 1);
  const auto vehicle = r.get<std::string>();
  if (vehicle != vehicle_id_) {
    r.fail("the state is of the sensors of vehicle '" + vehicle + "', not '" + vehicle_id_ + "'");
  }
  auto id = [](const auto& s) -> const std::string& { return s.config().id; };
  auto pid = [](const auto& s) -> const std::string& { return s->config().id; };
  load_kind(r, gps_, id, "gps");
  load_kind(r, imus_, id, "imu");
  load_kind(r, magnetometers_, id, "magnetometer");
  load_kind(r, tachometers_, id, "tachometer");
  load_kind(r, cameras_, pid, "camera");
  load_kind(r, lidars_, pid, "lidar");
  if (version >= 2) {
    load_kind(r, radars_, pid, "radar");
  } else if (!radars_.empty()) {
    r.fail("the state holds no radars, this rig has " + std::to_string(radars_.size()));
  }
  r.end();
}

}  // namespace syndds::sensors
