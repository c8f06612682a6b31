#include "sensors/rig.hpp"

#include <sstream>
#include <stdexcept>

namespace syndds::sensors {
namespace {

std::string fmt(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
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
  return b;
}

}  // namespace syndds::sensors
