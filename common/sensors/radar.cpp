#include "sensors/radar.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "core/state_io.hpp"
#include "sensors/random.hpp"
#include "sensors/ray_packets.hpp"

namespace syndds::sensors {
namespace {

constexpr int kColumnsPerTask = 8;  // horizontal ray columns per thread-pool task

std::uint32_t find(std::vector<std::uint32_t>& parent, std::uint32_t i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

// The smaller root becomes the parent: a cluster's root is its first ray.
void unite(std::vector<std::uint32_t>& parent, std::uint32_t a, std::uint32_t b) {
  a = find(parent, a);
  b = find(parent, b);
  if (a == b) return;
  if (a < b) {
    parent[b] = a;
  } else {
    parent[a] = b;
  }
}

double db(double v) { return v > 0.0 ? 10.0 * std::log10(v) : -1000.0; }

}  // namespace

RadarSensor::RadarSensor(const RadarConfig& config, std::string vehicle_id, std::uint64_t seed,
                         double tick_s)
    : config_(config),
      vehicle_id_(std::move(vehicle_id)),
      seed_(seed),
      pool_(config.threads),
      clock_(config.rate_hz, config.lag_s, tick_s, config.id) {
  if (const auto error = config_error(config); !error.empty()) {
    throw std::invalid_argument(config.id + ": " + error);
  }
  const int n = rays();
  directions_.resize(static_cast<std::size_t>(n) * 3);
  solid_angle_.resize(static_cast<std::size_t>(n));
  const double d_az = deg_to_rad(config.hfov_max_deg - config.hfov_min_deg) / config.horizontal_rays;
  const double d_el = deg_to_rad(config.vfov_max_deg - config.vfov_min_deg) / config.vertical_rays;
  for (int h = 0; h < config.horizontal_rays; ++h) {
    const double az = azimuth_rad(h);
    for (int v = 0; v < config.vertical_rays; ++v) {
      const double el = elevation_rad(v);
      const std::size_t r = static_cast<std::size_t>(h) * config.vertical_rays + v;
      directions_[3 * r] = static_cast<float>(std::cos(el) * std::cos(az));
      directions_[3 * r + 1] = static_cast<float>(std::cos(el) * std::sin(az));
      directions_[3 * r + 2] = static_cast<float>(std::sin(el));
      solid_angle_[r] = static_cast<float>(d_az * d_el * std::cos(el));
    }
  }
  returns_.resize(static_cast<std::size_t>(n));
  parent_.resize(static_cast<std::size_t>(n));
}

double RadarSensor::azimuth_rad(int h) const {
  return deg_to_rad(config_.hfov_min_deg + (h + 0.5) * (config_.hfov_max_deg - config_.hfov_min_deg) /
                                               config_.horizontal_rays);
}

double RadarSensor::elevation_rad(int v) const {
  return deg_to_rad(config_.vfov_min_deg + (v + 0.5) * (config_.vfov_max_deg - config_.vfov_min_deg) /
                                               config_.vertical_rays);
}

Pose RadarSensor::sensor_pose(const Scene& scene) const {
  return mounted_pose(scene, vehicle_id_, config_.mount.pose, config_.id);
}

Vec3 RadarSensor::sensor_velocity(const Scene& scene, const Pose& pose) const {
  if (vehicle_id_.empty()) return Vec3::Zero();
  return scene.vehicle_point_velocity(vehicle_id_, pose.position);
}

void RadarSensor::trace(const Scene& scene, const Pose& pose, const Vec3& sensor_velocity,
                        int hidden_slot) {
  if (!scene.committed()) throw std::logic_error("radar scan: scene not committed");
  const RayFrame frame(pose);
  const auto tnear = static_cast<float>(config_.min_range_m);
  const auto tfar = static_cast<float>(config_.max_range_m);
  const bool remove_ground = config_.ground == RadarGround::remove;
  const int per_column = config_.vertical_rays;
  const int tasks = (config_.horizontal_rays + kColumnsPerTask - 1) / kColumnsPerTask;
  RTCScene handle = scene.handle();
  pool_.run(tasks, [&](int task) {
    const int h0 = task * kColumnsPerTask;
    const int h1 = std::min(config_.horizontal_rays, h0 + kColumnsPerTask);
    const std::size_t r0 = static_cast<std::size_t>(h0) * per_column;
    const std::size_t r1 = static_cast<std::size_t>(h1) * per_column;
    HidingContext ctx;
    init_hiding_context(ctx, hidden_slot, true);
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    float dir[16][3];
    for (std::size_t base = r0; base < r1; base += 16) {
      fill_packet(rh, valid, dir, base, r1, directions_.data(), frame, tnear, tfar);
      intersect(true, valid, handle, &ctx.context, rh);
      for (int l = 0; l < 16; ++l) {
        if (!valid[l]) continue;
        const std::size_t r = base + static_cast<std::size_t>(l);
        RadarReturn& ret = returns_[r];
        ret = RadarReturn{};
        const unsigned geom = rh.hit.geomID[l];
        if (geom == RTC_INVALID_GEOMETRY_ID) continue;
        const Surface& s = scene.surface(geom);
        if (s.kind == SurfaceKind::terrain && remove_ground) continue;
        const double rho = s.kind == SurfaceKind::vehicle   ? config_.reflectivity.vehicle
                           : s.kind == SurfaceKind::terrain ? config_.reflectivity.terrain
                                                            : config_.reflectivity.of_obstacle(s.label);
        const Vec3 u(dir[l][0], dir[l][1], dir[l][2]);
        const Vec3 n(rh.hit.Ng_x[l], rh.hit.Ng_y[l], rh.hit.Ng_z[l]);
        const double cosi = std::abs(n.dot(u)) / std::max(n.norm(), 1e-30);
        const double range = rh.ray.tfar[l];
        const Vec3 point = pose.position + range * u;
        const Vec3 v = scene.point_velocity(geom, point) - sensor_velocity;
        const double sigma = rho * cosi * range * range * solid_angle_[r];
        const float* d = &directions_[3 * r];
        ret.range = static_cast<float>(range);
        ret.x = static_cast<float>(range * d[0]);
        ret.y = static_cast<float>(range * d[1]);
        ret.z = static_cast<float>(range * d[2]);
        ret.radial_speed = static_cast<float>(v.dot(u));
        ret.rcs = static_cast<float>(sigma);
        ret.power = static_cast<float>(sigma / (range * range * range * range));
        ret.kind = s.kind;
      }
    }
  });
}

void RadarSensor::cluster(std::vector<RadarDetection>& out) {
  const int H = config_.horizontal_rays, V = config_.vertical_rays;
  const auto n = static_cast<std::uint32_t>(returns_.size());
  std::iota(parent_.begin(), parent_.end(), 0u);
  const float range_gate = static_cast<float>(config_.range_gate_m);
  const float speed_gate = static_cast<float>(config_.speed_gate_mps);
  auto join = [&](std::uint32_t a, std::uint32_t b) {
    const RadarReturn& x = returns_[a];
    const RadarReturn& y = returns_[b];
    if (y.range <= 0.0f) return;
    if (std::abs(x.range - y.range) <= range_gate &&
        std::abs(x.radial_speed - y.radial_speed) <= speed_gate) {
      unite(parent_, a, b);
    }
  };
  for (int h = 0; h < H; ++h) {
    for (int v = 0; v < V; ++v) {
      const auto r = static_cast<std::uint32_t>(h * V + v);
      if (returns_[r].range <= 0.0f) continue;
      if (v + 1 < V) join(r, r + 1);
      if (h + 1 < H) {
        join(r, r + static_cast<std::uint32_t>(V));
        if (v + 1 < V) join(r, r + static_cast<std::uint32_t>(V) + 1);
        if (v > 0) join(r, r + static_cast<std::uint32_t>(V) - 1);
      }
    }
  }
  // Sums per root (roots are first rays, so clusters come out in ray order).
  struct Sum {
    std::uint32_t root = 0, points = 0;
    double power = 0, rcs = 0, x = 0, y = 0, z = 0, speed = 0;
  };
  std::vector<Sum> sums;
  std::vector<std::uint32_t> slot(n, UINT32_MAX);
  for (std::uint32_t r = 0; r < n; ++r) {
    const RadarReturn& ret = returns_[r];
    if (ret.range <= 0.0f) continue;
    const std::uint32_t root = find(parent_, r);
    if (slot[root] == UINT32_MAX) {
      slot[root] = static_cast<std::uint32_t>(sums.size());
      sums.push_back({root});
    }
    Sum& s = sums[slot[root]];
    const double p = ret.power;
    ++s.points;
    s.power += p;
    s.rcs += ret.rcs;
    s.x += p * ret.x;
    s.y += p * ret.y;
    s.z += p * ret.z;
    s.speed += p * ret.radial_speed;
  }
  struct Candidate {
    RadarDetection d;
    double power;
    std::uint32_t root;
  };
  std::vector<Candidate> found;
  for (const Sum& s : sums) {
    if (s.points < static_cast<std::uint32_t>(config_.min_points) || !(s.power > 0.0)) continue;
    const double strength = db(s.power);
    if (strength < config_.min_strength_db) continue;
    RadarDetection d;
    const double x = s.x / s.power, y = s.y / s.power, z = s.z / s.power;
    d.x = static_cast<float>(x);
    d.y = static_cast<float>(y);
    d.z = static_cast<float>(z);
    d.range_m = static_cast<float>(std::sqrt(x * x + y * y + z * z));
    d.azimuth_rad = static_cast<float>(std::atan2(y, x));
    d.elevation_rad = static_cast<float>(std::atan2(z, std::hypot(x, y)));
    d.radial_speed_mps = static_cast<float>(s.speed / s.power);
    d.strength_db = static_cast<float>(strength);
    d.rcs_dbsm = static_cast<float>(db(s.rcs));
    d.points = s.points;
    found.push_back({d, s.power, s.root});
  }
  const auto keep = static_cast<std::size_t>(config_.max_detections);
  if (found.size() > keep) {
    std::stable_sort(found.begin(), found.end(),
                     [](const Candidate& a, const Candidate& b) { return a.power > b.power; });
    found.resize(keep);
  }
  std::sort(found.begin(), found.end(), [](const Candidate& a, const Candidate& b) {
    return a.d.range_m != b.d.range_m ? a.d.range_m < b.d.range_m : a.root < b.root;
  });
  out.clear();
  out.reserve(found.size());
  for (const auto& c : found) out.push_back(c.d);
}

RadarScan RadarSensor::scan(const Scene& scene, std::uint64_t noise_index) {
  RadarScan out;
  out.sensor_id = config_.id;
  out.pose = sensor_pose(scene);
  out.velocity = sensor_velocity(scene, out.pose);
  const int hidden =
      config_.hide_own_vehicle && !vehicle_id_.empty() ? scene.vehicle_slot(vehicle_id_) : -1;
  trace(scene, out.pose, out.velocity, hidden);
  cluster(out.detections);
  // Noise: two 64-bit hashes per detection, four normals from their 32-bit halves.
  const double sr = config_.range_noise_std_m, sa = config_.azimuth_noise_std_rad,
               se = config_.elevation_noise_std_rad, sv = config_.speed_noise_std_mps;
  if (sr == 0.0 && sa == 0.0 && se == 0.0 && sv == 0.0) return out;
  const std::uint64_t scan_key = mix64(seed_ ^ mix64(noise_index + 0x7AD4));
  const NormalTable& normal = NormalTable::instance();
  for (std::size_t i = 0; i < out.detections.size(); ++i) {
    RadarDetection& d = out.detections[i];
    const std::uint64_t h1 = mix64(scan_key + 2 * i), h2 = mix64(scan_key + 2 * i + 1);
    const double range =
        std::max(0.0, d.range_m + sr * normal(static_cast<std::uint32_t>(h1)));
    const double az = d.azimuth_rad + sa * normal(static_cast<std::uint32_t>(h1 >> 32));
    const double el = d.elevation_rad + se * normal(static_cast<std::uint32_t>(h2));
    d.radial_speed_mps += static_cast<float>(sv * normal(static_cast<std::uint32_t>(h2 >> 32)));
    d.range_m = static_cast<float>(range);
    d.azimuth_rad = static_cast<float>(az);
    d.elevation_rad = static_cast<float>(el);
    d.x = static_cast<float>(range * std::cos(el) * std::cos(az));
    d.y = static_cast<float>(range * std::cos(el) * std::sin(az));
    d.z = static_cast<float>(range * std::sin(el));
  }
  return out;
}

void RadarSensor::update(const Scene& scene, double time_s) {
  const std::int64_t tick = clock_.tick_of(time_s);
  if (const auto k = clock_.trigger(tick)) {
    RadarScan s = scan(scene, *k);
    s.stamp = clock_.stamp(*k, tick);
    queue_.push(std::move(s), tick + clock_.lag_ticks());
  }
}

std::vector<RadarScan> RadarSensor::take_available(double now_s) {
  return queue_.take_ready(clock_.tick_of(now_s));
}

// Kept: the clock and the waiting scans. Not kept: the returns and the union-find (work arrays
// of one scan); the noise is a pure function of (seed, scan, detection).
template <typename Archive>
void RadarSensor::state(Archive& a) {
  a.begin("radar", 1);
  if constexpr (std::is_same_v<Archive, core::StateWriter>) {
    a.io(seed_);
    clock_.save_state(a);
    queue_.save_state(a, [](core::StateWriter& w, const RadarScan& s) { w.io(s); });
  } else {
    if (a.template get<std::uint64_t>() != seed_) {
      a.fail(config_.id + ": the state is of a radar with another noise seed (another scenario "
             "seed or vehicle)");
    }
    clock_.load_state(a, config_.id);
    queue_.load_state(a, [](core::StateReader& r, RadarScan& s) { r.io(s); });
  }
  a.end();
}

template void RadarSensor::state(core::StateWriter&);
template void RadarSensor::state(core::StateReader&);

}  // namespace syndds::sensors
