#pragma once
// Helpers shared by the vehicle tests: vehicle files, a speed-holding driver, terrains.
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "terrain/heightmap_terrain.hpp"
#include "terrain/terrain.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::vehicle::testing {

inline VehicleParams load(const std::string& name) {
  return load_vehicle_params(std::string(SYNDDS_TEST_CONFIG_DIR) + "/vehicles/" + name + ".yaml");
}

inline std::shared_ptr<terrain::FlatTerrain> flat(double friction = 0.8) {
  return std::make_shared<terrain::FlatTerrain>(0.0, friction);
}

/// A plane h = slope_x * x as a height map (for slopes and height-map vehicle tests).
inline std::shared_ptr<terrain::HeightmapTerrain> ramp(double slope_x, double size_m = 200.0,
                                                       double friction = 0.8) {
  const int n = 41;
  std::vector<double> h(static_cast<std::size_t>(n * n));
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      h[static_cast<std::size_t>(j * n + i)] = slope_x * (-0.5 * size_m + i * size_m / (n - 1));
    }
  }
  return std::make_shared<terrain::HeightmapTerrain>(n, n, std::move(h), size_m, size_m,
                                                     friction);
}

/// Forward speed of the chassis reference point along its heading.
inline double forward_speed(const VehicleSnapshot& s) {
  return s.linear_velocity.dot(s.pose.orientation * Vec3::UnitX());
}

/// Proportional speed hold: throttle above the target band, brake when too fast.
inline DriverInputs hold_speed(const VehicleSnapshot& s, double target_mps, double steering,
                               double gain = 0.5) {
  const double err = target_mps - forward_speed(s);
  DriverInputs in;
  in.steering = steering;
  in.throttle = err > 0 ? std::min(1.0, gain * err) : 0.0;
  in.braking = err < -0.3 ? std::min(1.0, -0.2 * err) : 0.0;
  return in;
}

inline void run(VehicleModel& m, double seconds, double dt = 0.002) {
  const long n = std::lround(seconds / dt);
  for (long i = 0; i < n; ++i) m.advance(dt);
}

/// Runs while holding a speed and a steering input; the controller updates every 10 ms.
inline void drive(VehicleModel& m, double seconds, double target_mps, double steering,
                  double dt = 0.002) {
  const long n = std::lround(seconds / dt);
  for (long i = 0; i < n; ++i) {
    if (i % 5 == 0) m.set_inputs(hold_speed(m.snapshot(), target_mps, steering));
    m.advance(dt);
  }
}

}  // namespace syndds::vehicle::testing
