#pragma once
// Shared rigs for the SCM tests: presets from config/terrain, and a rigid body with one vertical
// degree of freedom driven onto the grid (semi-implicit Euler).
#include <cmath>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "scm/scm_params.hpp"
#include "scm/scm_terrain.hpp"

namespace syndds::scm::test {

/// The HMMWV's wheel, and the step the SCM tests advance by (s).
inline constexpr double kHmmwvWheelRadius = 0.467;
inline constexpr double kHmmwvWheelWidth = 0.254;
inline constexpr double kStepS = 2e-3;

/// True when both hold the same doubles, bit for bit.
inline bool bit_equal(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

inline SoilPreset preset(const std::string& name) {
  return load_soil_preset_file(std::string(SYNDDS_TEST_CONFIG_DIR) + "/terrain/scm_" + name +
                               ".yaml");
}

inline ScmParams params(const std::string& name, double spacing_m, double half_size_m = 2.0,
                        int threads = 1) {
  ScmParams p;
  const SoilPreset s = preset(name);
  p.soil = s.soil;
  p.bulldozing = s.bulldozing;
  p.grid.spacing_m = spacing_m;
  p.grid.x_min_m = -half_size_m;
  p.grid.x_max_m = half_size_m;
  p.grid.y_min_m = -half_size_m;
  p.grid.y_max_m = half_size_m;
  p.threads = threads;
  return p;
}

/// A body free to move vertically under an applied downward load W(t), with mass m and an extra
/// dashpot c (the rig's, to reach the static state without overshoot). Horizontal motion and
/// spin are prescribed through body.linear_velocity.x/y and body.angular_velocity.
struct VerticalRig {
  ContactBody body;
  double mass_kg = 1.0;
  double damping_nspm = 0.0;
  double time_s = 0.0;
  terrain::WheelLoad last;

  void step(ScmTerrain& terrain, double load_n, double dt) {
    terrain::WheelLoad load;
    terrain.compute_body_loads(std::span<const ContactBody>(&body, 1), dt,
                               std::span<terrain::WheelLoad>(&load, 1));
    last = load;
    double& vz = body.linear_velocity.z();
    const double fz = load.force.z() - load_n - damping_nspm * vz;
    vz += dt * fz / mass_kg;
    body.pose.position += dt * body.linear_velocity;
    time_s += dt;
  }

  /// Runs until t_end under load(t).
  void run(ScmTerrain& terrain, const std::function<double(double)>& load, double t_end,
           double dt) {
    while (time_s < t_end - 0.5 * dt) step(terrain, load(time_s), dt);
  }
};

/// Linear ramp from w0 at t0 to w1 at t1, constant outside.
inline std::function<double(double)> ramp(double t0, double w0, double t1, double w1) {
  return [=](double t) {
    if (t <= t0) return w0;
    if (t >= t1) return w1;
    return w0 + (w1 - w0) * (t - t0) / (t1 - t0);
  };
}

}  // namespace syndds::scm::test
