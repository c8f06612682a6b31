#pragma once
// Parameters of the Soil Contact Model (SCM): soil law, bulldozing, grid. Plain structs that code
// can fill in directly, plus strict YAML readers (unknown keys are errors naming file:line).
//
// Preset files live in config/terrain/scm_<name>.yaml (soft, mid, hard) and hold one `soil:`
// mapping and one optional `bulldozing:` mapping.
#include <optional>
#include <string>

#include "core/config_files.hpp"
#include "core/yaml.hpp"

namespace syndds::scm {

/// Bekker-Wong / Mohr-Coulomb / Janosi-Hanamoto soil parameters (SI units).
struct SoilParams {
  double bekker_kphi = 2e6;                 // Pa / m^n        frictional modulus
  double bekker_kc = 0.0;                   // Pa / m^(n-1)    cohesive modulus (divided by b)
  double bekker_n = 1.1;                    // -               sinkage exponent
  double cohesion_pa = 0.0;                 // Pa              Mohr cohesion c
  double friction_angle_deg = 30;           // deg             Mohr friction angle phi
  double janosi_shear_m = 0.01;             // m               Janosi shear modulus K
  double elastic_stiffness_pa_per_m = 2e8;  // Pa/m  Ke, unloading/reloading stiffness
  double damping_pa_s_per_m = 3e4;          // Pa s/m R, normal-velocity damping
};

/// Material displaced from under a contact patch to the rim of the rut, then eroded to a
/// maximum slope. Off by default (as in Chrono).
struct BulldozingParams {
  bool enabled = false;
  double erosion_angle_deg = 55.0;  // slopes steeper than this flow downhill
  double flow_factor = 1.0;         // rim volume gained / volume pressed down (1: conserving)
  int iterations = 5;               // erosion smoothing sweeps per step
  int propagations = 10;            // rings around the rim that erosion may reach
};

/// Grid geometry. Vertex (i, j) sits at world (i * spacing_m, j * spacing_m); the deformable
/// area is the set of vertices inside [x_min_m, x_max_m] x [y_min_m, y_max_m].
struct GridParams {
  double spacing_m = 0.05;
  double x_min_m = -50.0;
  double x_max_m = 50.0;
  double y_min_m = -50.0;
  double y_max_m = 50.0;
  double base_height_m = 0.0;  // undeformed height when no base surface is given
};

/// Everything an ScmTerrain needs.
struct ScmParams {
  SoilParams soil;
  BulldozingParams bulldozing;
  GridParams grid;
  /// A vertex belongs to a contact patch (the A and P of b = 2 A / P) if the body is less than
  /// this far above the unloaded soil there; only vertices the body is below carry load.
  /// Chrono's SCM "test height" (SCMTerrain::SetTestHeight, default 0.1 m).
  double patch_test_height_m = 0.1;
  /// Shear damping time beta (s): the shear stress takes the mobilisation the slip would reach
  /// beta later, i.e. stiffness-proportional damping of the Janosi shear spring. It damps the
  /// rocking of a body at rest on soft soil; 0 gives the plain law (docs/scm.md, Deviations).
  double shear_damping_time_s = 0.005;
  int threads = 1;  // ray-casting threads (results are bit-identical for any count)
  /// Interest management (docs/scm.md, "Interest management"): a vehicle process merges the
  /// other vehicles' deformations only within this distance of its chassis; records beyond it
  /// wait, per tile, exactly as the merge would leave them, and are merged when the vehicle
  /// comes near. 0 merges everything at once. Results are the same either way.
  double interest_radius_m = 12.0;
  /// Soil routing (docs/scm.md, "Routing"; needs interest_radius_m > 0 and the recorder, which
  /// keeps the whole soil): a vehicle receives only the records inside its subscription box
  /// (the interest square plus a margin, in tiles), addressed to it by their writers, and the
  /// recorder's copy of tiles as they enter the box. Results are the same either way.
  bool routing = false;
  /// Footprint vertices per thread below which a step runs on the calling thread only (waking
  /// workers costs tens of microseconds). Does not change results.
  int thread_min_vertices = 4096;
};

/// Chrono SynChrono presets (SynChrono's SCM demos), the same numbers the YAML files hold.
SoilParams soil_preset(const std::string& name);  // "soft", "mid", "hard"

/// Reads a `soil:` mapping.
SoilParams parse_soil_params(const YamlNode& node);
/// Reads a `bulldozing:` mapping; keys not given keep the values of `defaults`.
BulldozingParams parse_bulldozing_params(const YamlNode& node, const BulldozingParams& defaults);

/// A preset file: `soil:` (required) and `bulldozing:` (optional).
struct SoilPreset {
  SoilParams soil;
  BulldozingParams bulldozing;
};
/// With `files`, the file is read through it (recorded for the run's fingerprint as `role`).
SoilPreset load_soil_preset_file(const std::string& file, ConfigFiles* files = nullptr,
                                 const std::string& role = "soil preset");

/// Reads a scenario terrain block:
///   type: scm              # optional (if present it must say scm)
///   preset: mid            # config/terrain/scm_<preset>.yaml under `terrain_config_dir`
///   soil: {...}            # instead of preset (exactly one of the two)
///   spacing_m: 0.05
///   area: {x_min_m: -50, x_max_m: 50, y_min_m: -50, y_max_m: 50}
///   base_height_m: 0       # optional
///   threads: 1             # optional
///   interest_radius_m: 12  # optional; 0 = merge every deformation at once
///   routing: false         # optional; true: each vehicle receives only nearby records
///   patch_test_height_m: 0.1  # optional
///   shear_damping_time_s: 0.005  # optional
///   bulldozing: {...}      # optional, overrides the preset's
/// With `files`, the preset file is read through it (see load_soil_preset_file).
ScmParams parse_scm_params(const YamlNode& node, const std::string& terrain_config_dir,
                           ConfigFiles* files = nullptr);

/// Throws ConfigError if a parameter is out of range (used by the readers and by ScmTerrain).
void validate(const ScmParams& params);

}  // namespace syndds::scm
