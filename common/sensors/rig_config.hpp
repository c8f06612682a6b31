#pragma once
// Sensor rigs (config/sensors/*.yaml): the sensors mounted on one vehicle, read strictly
// (unknown keys are errors naming file:line:column) into plain structs, each sensor checked
// against its budget in constant time. Nothing here renders or allocates per ray or pixel;
// VehicleSensors (rig.hpp) builds the sensors from a SensorRig. Schema, defaults and budgets:
// docs/sensors.md.
#include <string>
#include <vector>

#include "core/yaml.hpp"
#include "sensors/geodesy.hpp"
#include "sensors/sensor_config.hpp"

namespace syndds::sensors {

struct SensorRig {
  std::string name;
  std::string file;
  Geodetic geodetic_origin = kDefaultOrigin;
  SceneConfig scene;  // lighting and tessellation for the renderers ("scene:" block)
  std::vector<CameraConfig> cameras;
  std::vector<LidarConfig> lidars;
  std::vector<RadarConfig> radars;
  std::vector<GpsConfig> gps;
  std::vector<ImuConfig> imus;
  std::vector<MagnetometerConfig> magnetometers;
  std::vector<TachometerConfig> tachometers;
  std::vector<std::string> sensor_ids;  // in file order

  /// Cameras, lidars and radars: ray traced in the vehicle's sensor process.
  bool has_rendered_sensors() const {
    return !cameras.empty() || !lidars.empty() || !radars.empty();
  }
};

/// Reads a rig file; ConfigError (file:line:column: key path: message) on any problem.
SensorRig load_sensor_rig(const std::string& file);
SensorRig parse_sensor_rig(const YamlNode& root);
/// Path of a rig by name ("default" -> <config_dir>/sensors/default.yaml), or the argument
/// itself when it names an existing file.
std::string sensor_rig_path(const std::string& name_or_path, const std::string& config_dir);

}  // namespace syndds::sensors
