#pragma once
// VehicleSensors: every sensor of a rig (rig_config.hpp) built for one vehicle, with seeds
// derived from the scenario seed. Schema and defaults of the rig files: docs/sensors.md.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/yaml.hpp"
#include "sensors/camera.hpp"
#include "sensors/geodesy.hpp"
#include "sensors/interoceptive.hpp"
#include "sensors/lidar.hpp"
#include "sensors/radar.hpp"
#include "sensors/rig_config.hpp"
#include "sensors/scene.hpp"

namespace syndds::sensors {

/// Seed of one sensor's random stream: derive_seed(scenario_seed, "<vehicle>/<sensor>").
std::uint64_t sensor_seed(std::uint64_t scenario_seed, const std::string& vehicle_id,
                          const std::string& sensor_id);

/// Samples of every interoceptive sensor of a rig that became available.
struct InteroceptiveBatch {
  std::vector<GpsSample> gps;
  std::vector<ImuSample> imu;
  std::vector<MagnetometerSample> magnetometer;
  std::vector<TachometerSample> tachometer;
  bool empty() const {
    return gps.empty() && imu.empty() && magnetometer.empty() && tachometer.empty();
  }
};

/// Camera frames, lidar and radar scans that became available.
struct RenderedBatch {
  std::vector<CameraFrame> camera;
  std::vector<LidarScan> lidar;
  std::vector<RadarScan> radar;
  bool empty() const { return camera.empty() && lidar.empty() && radar.empty(); }
};

/// Which sensors of a rig a process builds: the vehicle process simulates the interoceptive
/// ones, the sensor process renders the cameras, lidars and radars (a renderer starts its threads and
/// allocates per pixel or ray, so no other process builds one).
enum class SensorSet { all, interoceptive, rendered };

/// Every sensor of a rig on one vehicle (or those of one SensorSet).
///  - interoceptive sensors: update_dynamics(snapshot) after every dynamics step (step_s);
///  - cameras, lidars and radars: update_rendered(scene, t) once per frame (heartbeat_s) after the
///    scene holds every vehicle's pose and terrain change for time t and was committed;
///  - take_*(now): samples whose available time (measurement + lag) is <= now.
class VehicleSensors {
 public:
  /// Throws ConfigError (naming the rig file and sensor) when a sensor does not fit the time
  /// grid (rate above the feed rate, exposure longer than period or lag).
  VehicleSensors(const SensorRig& rig, std::string vehicle_id, std::uint64_t scenario_seed,
                 double step_s, double heartbeat_s, SensorSet set = SensorSet::all);
  const std::string& vehicle_id() const { return vehicle_id_; }

  void update_dynamics(const vehicle::VehicleSnapshot& snapshot);
  void update_rendered(const Scene& scene, double time_s);
  /// Whether update_rendered(scene, time_s) may render (conservative: true whenever the rig
  /// has a lidar or a radar): the scene needs a commit before it only then.
  bool may_render(double time_s) const;
  InteroceptiveBatch take_interoceptive(double now_s);
  RenderedBatch take_rendered(double now_s);

  std::vector<GpsSensor>& gps() { return gps_; }
  std::vector<ImuSensor>& imus() { return imus_; }
  std::vector<MagnetometerSensor>& magnetometers() { return magnetometers_; }
  std::vector<TachometerSensor>& tachometers() { return tachometers_; }
  std::vector<std::unique_ptr<CameraSensor>>& cameras() { return cameras_; }
  std::vector<std::unique_ptr<LidarSensor>>& lidars() { return lidars_; }
  std::vector<std::unique_ptr<RadarSensor>>& radars() { return radars_; }

  /// Checkpoint state of every sensor built (between frames; docs/sensors.md, "Checkpoint
  /// state"): random streams, bias walks, schedules, samples waiting for their lag, open
  /// exposures. The scene the rendered sensors look at is not part of it.
  void save_state(core::StateWriter& w) const;
  /// Restores into sensors built from the same rig, vehicle, seed, step and frame. Throws
  /// core::StateError naming the sensor when the state is of another vehicle or rig.
  void load_state(core::StateReader& r);

 private:
  std::string vehicle_id_;
  std::vector<GpsSensor> gps_;
  std::vector<ImuSensor> imus_;
  std::vector<MagnetometerSensor> magnetometers_;
  std::vector<TachometerSensor> tachometers_;
  std::vector<std::unique_ptr<CameraSensor>> cameras_;
  std::vector<std::unique_ptr<LidarSensor>> lidars_;
  std::vector<std::unique_ptr<RadarSensor>> radars_;
};

}  // namespace syndds::sensors
