// SCM benchmark: cost of one compute_wheel_loads call for the four wheels of an HMMWV-sized
// vehicle (radius 0.467 m, width 0.254 m, about 6 kN each, driven at 3 m/s with 10 % slip,
// 2 ms steps) against grid spacing and thread count, and the size of the per-frame change
// lists (0.01 s frames) that deformation sync publishes: as 40-byte records (B/frame) and
// packed as they travel (packB/frm, bytes per vertex B/vtx; protocol/vertex_codec.hpp).
//
//   bench_scm [--steps N] [--repeat R] [--preset soft|mid|hard|all] [--quick]
//
// With --repeat R every configuration runs R times and the fastest run is reported (the other
// columns do not depend on timing): on a shared machine this filters out other processes.
//
// Numbers go into docs/scm.md with the command that produced them.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "protocol/vertex_codec.hpp"
#include "scm/scm_params.hpp"
#include "scm/scm_terrain.hpp"

using namespace syndds;
using namespace syndds::scm;

namespace {

struct Row {
  std::string preset;
  double spacing = 0.0;
  int threads = 1;
  bool forced = false;  // threads used even for small steps (thread_min_vertices = 1)
  bool bulldozing = false;
  double us_per_call = 0.0;
  double rtf = 0.0;  // wall time of the terrain calls / simulated time
  double footprint = 0.0, covered = 0.0, contacts = 0.0, patch_vertices = 0.0, domain = 0.0;
  double bytes_per_frame = 0.0, max_bytes_per_frame = 0.0;
  double packed_bytes_per_frame = 0.0, packed_bytes_per_vertex = 0.0;
  double sinkage_mm = 0.0;
  std::size_t stored = 0;
};

Row run(const std::string& preset, double spacing, int threads, bool forced, bool bulldozing,
        int steps) {
  ScmParams p;
  const SoilPreset s =
      load_soil_preset_file(std::string(SYNDDS_CONFIG_DIR) + "/terrain/scm_" + preset + ".yaml");
  p.soil = s.soil;
  p.bulldozing = s.bulldozing;
  p.bulldozing.enabled = bulldozing;
  p.grid.spacing_m = spacing;
  p.grid.x_min_m = -10;
  p.grid.x_max_m = 200;
  p.grid.y_min_m = -10;
  p.grid.y_max_m = 10;
  p.threads = threads;
  if (forced) p.thread_min_vertices = 1;
  ScmTerrain terrain(p);

  const double r = 0.467, width = 0.254, load = 6000.0, mass = 60.0, dt = 2e-3;
  const double v = 3.0, slip = 0.10;
  const double xs[2] = {1.689, -1.689}, ys[2] = {0.9095, -0.9095};
  std::vector<terrain::WheelBodyState> wheels(4);
  std::vector<terrain::WheelLoad> loads(4);
  for (int k = 0; k < 4; ++k) {
    auto& w = wheels[static_cast<std::size_t>(k)];
    w.pose.position = Vec3(xs[k / 2], ys[k % 2], r);
    w.linear_velocity = Vec3(v, 0, 0);
    w.angular_velocity = Vec3(0, (1 + slip) * v / r, 0);
    w.radius_m = r;
    w.width_m = width;
  }
  // Each wheel carries its share of the vehicle on a stiff suspension-like vertical dof.
  auto step = [&] {
    terrain.compute_wheel_loads(wheels, dt, loads);
    for (std::size_t k = 0; k < 4; ++k) {
      auto& w = wheels[k];
      const double fz = loads[k].force.z() - load - 2000.0 * w.linear_velocity.z();
      w.linear_velocity.z() += dt * fz / mass;
      w.pose.position += dt * w.linear_velocity;
    }
  };
  // Warm-up: settle into the soil and reach a steady rut (1 s).
  for (int n = 0; n < 500; ++n) {
    step();
    if (n % 5 == 4) (void)terrain.take_local_changes();
  }
  Row row;
  row.preset = preset;
  row.spacing = spacing;
  row.threads = threads;
  row.forced = forced;
  row.bulldozing = bulldozing;
  double seconds = 0.0;
  double bytes = 0.0, packed = 0.0, vertices = 0.0;
  int frames = 0;
  for (int n = 0; n < steps; ++n) {
    const auto t0 = std::chrono::steady_clock::now();
    terrain.compute_wheel_loads(wheels, dt, loads);
    const auto t1 = std::chrono::steady_clock::now();
    seconds += std::chrono::duration<double>(t1 - t0).count();
    const auto& st = terrain.last_step_stats();
    row.footprint += static_cast<double>(st.footprint_vertices);
    row.covered += static_cast<double>(st.covered_vertices);
    row.contacts += static_cast<double>(st.contact_vertices);
    row.patch_vertices += static_cast<double>(st.patch_vertices);
    row.domain += static_cast<double>(st.bulldozing_domain);
    for (std::size_t k = 0; k < 4; ++k) {
      auto& w = wheels[k];
      const double fz = loads[k].force.z() - load - 2000.0 * w.linear_velocity.z();
      w.linear_velocity.z() += dt * fz / mass;
      w.pose.position += dt * w.linear_velocity;
      row.sinkage_mm += 1e3 * loads[k].sinkage_m / 4.0;
    }
    if (n % 5 == 4) {  // 0.01 s frame boundary
      const auto changes = terrain.take_local_changes();
      const double b = static_cast<double>(changes.size() * sizeof(VertexChange));
      bytes += b;
      std::vector<proto::TerrainVertexMsg> records;
      records.reserve(changes.size());
      for (const VertexChange& c : changes) {
        records.push_back({c.i, c.j, c.level_m, c.level_initial_m, c.sinkage_plastic_m,
                           c.sigma_yield_pa});
      }
      packed += static_cast<double>(proto::packed_size(records));
      vertices += static_cast<double>(changes.size());
      row.max_bytes_per_frame = std::max(row.max_bytes_per_frame, b);
      ++frames;
    }
  }
  row.us_per_call = 1e6 * seconds / steps;
  row.rtf = seconds / (steps * dt);
  row.footprint /= steps;
  row.covered /= steps;
  row.contacts /= steps;
  row.patch_vertices /= steps;
  row.domain /= steps;
  row.sinkage_mm /= steps;
  row.bytes_per_frame = bytes / std::max(frames, 1);
  row.packed_bytes_per_frame = packed / std::max(frames, 1);
  row.packed_bytes_per_vertex = packed / std::max(vertices, 1.0);
  row.stored = terrain.stored_vertices();
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  int steps = 2500;
  int repeat = 1;
  std::string which = "all";
  bool quick = false;
  for (int a = 1; a < argc; ++a) {
    if (!std::strcmp(argv[a], "--steps") && a + 1 < argc) {
      steps = std::max(1, std::atoi(argv[++a]));
    } else if (!std::strcmp(argv[a], "--repeat") && a + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++a]));
    } else if (!std::strcmp(argv[a], "--preset") && a + 1 < argc) {
      which = argv[++a];
    } else if (!std::strcmp(argv[a], "--quick")) {
      quick = true;
    } else {
      std::fprintf(stderr,
                   "usage: bench_scm [--steps N] [--repeat R] [--preset soft|mid|hard|all] "
                   "[--quick]\n");
      return 2;
    }
  }
  std::vector<std::string> presets;
  if (which == "all") {
    presets = {"soft", "mid", "hard"};
  } else {
    presets = {which};
  }
  const std::vector<double> spacings =
      quick ? std::vector<double>{0.05} : std::vector<double>{0.1, 0.05, 0.025};
  std::printf(
      "SCM benchmark: 4 wheels r 0.467 m w 0.254 m, 6 kN each, 3 m/s, 10 %% slip, "
      "dt 2 ms, %d timed steps after 500 warm-up steps, best of %d\n",
      steps, repeat);
  std::printf("thr: worker threads (f: forced to split even small steps, thread_min_vertices 1)\n");
  std::printf("%-5s %7s %4s %5s %10s %9s %9s %8s %8s %8s %8s %10s %10s %8s %10s %6s\n", "soil", "spacing",
              "thr", "bulld", "us/call", "RTF", "footprnt", "covered", "contact", "patchv",
              "domain", "B/frame", "maxB/frm", "sink_mm", "packB/frm", "B/vtx");
  for (const auto& preset : presets) {
    for (double spacing : spacings) {
      struct Config {
        int threads;
        bool forced;
        bool bulldozing;
      };
      for (const Config c : {Config{1, false, false}, Config{1, false, true},
                             Config{2, false, false}, Config{2, true, false}}) {
        Row r = run(preset, spacing, c.threads, c.forced, c.bulldozing, steps);
        for (int k = 1; k < repeat; ++k) {
          const Row again = run(preset, spacing, c.threads, c.forced, c.bulldozing, steps);
          if (again.us_per_call < r.us_per_call) r = again;
        }
        std::printf(
            "%-5s %7.3f %3d%1s %5s %10.2f %9.4f %9.0f %8.0f %8.0f %8.0f %8.0f %10.0f %10.0f "
            "%8.1f %10.0f %6.1f\n",
            r.preset.c_str(), r.spacing, r.threads, r.forced ? "f" : "",
            r.bulldozing ? "on" : "off", r.us_per_call, r.rtf, r.footprint, r.covered, r.contacts,
            r.patch_vertices, r.domain, r.bytes_per_frame, r.max_bytes_per_frame, r.sinkage_mm,
            r.packed_bytes_per_frame, r.packed_bytes_per_vertex);
        std::fflush(stdout);
      }
    }
  }
  return 0;
}
