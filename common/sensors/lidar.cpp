#include "sensors/lidar.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "core/state_io.hpp"
#include "sensors/random.hpp"
#include "sensors/ray_packets.hpp"

namespace syndds::sensors {
namespace {
constexpr int kSamplesPerTask = 32;  // azimuth samples per thread-pool task
}

LidarRenderer::LidarRenderer(const LidarConfig& config) : config_(config), pool_(config.threads) {
  if (config.channels < 1 || config.channels > 1024 || config.samples < 1 ||
      config.samples > 65535) {
    throw std::invalid_argument(config.id + ": channels must be 1..1024, samples 1..65535");
  }
  if (!(config.max_range_m > config.min_range_m) || config.min_range_m < 0.0) {
    throw std::invalid_argument(config.id + ": need 0 <= min_range_m < max_range_m");
  }
  if (config.vfov_max_deg < config.vfov_min_deg || config.hfov_max_deg < config.hfov_min_deg ||
      config.hfov_max_deg - config.hfov_min_deg > 360.0 + 1e-9 || config.vfov_min_deg < -90.0 ||
      config.vfov_max_deg > 90.0) {
    throw std::invalid_argument(config.id + ": bad field of view");
  }
  if (config.beam_samples < 1) throw std::invalid_argument(config.id + ": beam_samples >= 1");
  const int sub = config.beam_samples;
  directions_.resize(static_cast<std::size_t>(beams()) * sub * 3);
  std::size_t r = 0;
  for (int s = 0; s < config.samples; ++s) {
    for (int c = 0; c < config.channels; ++c) {
      const double az = azimuth_rad(s), el = elevation_rad(c);
      const Vec3 d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
      Vec3 e1 = d.cross(Vec3::UnitZ());
      if (e1.norm() < 1e-6) e1 = d.cross(Vec3::UnitX());
      e1.normalize();
      const Vec3 e2 = d.cross(e1);
      const double half = 0.5 * config.divergence_rad;
      for (int j = 0; j < sub; ++j, ++r) {
        Vec3 v = d;
        if (j > 0) {
          const double phi = 2.0 * std::numbers::pi * (j - 1) / (sub - 1);
          v = std::cos(half) * d + std::sin(half) * (std::cos(phi) * e1 + std::sin(phi) * e2);
        }
        for (int k = 0; k < 3; ++k) directions_[3 * r + k] = static_cast<float>(v[k]);
      }
    }
  }
  for (int c = 0; c < config.channels; ++c) {
    cos_el_.push_back(std::cos(elevation_rad(c)));
    sin_el_.push_back(std::sin(elevation_rad(c)));
  }
  for (int s = 0; s < config.samples; ++s) {
    cos_az_.push_back(std::cos(azimuth_rad(s)));
    sin_az_.push_back(std::sin(azimuth_rad(s)));
  }
  hits_range_.resize(static_cast<std::size_t>(beams()) * sub);
  hits_intensity_.resize(hits_range_.size());
}

double LidarRenderer::elevation_rad(int channel) const {
  if (config_.channels == 1) return deg_to_rad(0.5 * (config_.vfov_min_deg + config_.vfov_max_deg));
  return deg_to_rad(config_.vfov_min_deg + channel * (config_.vfov_max_deg - config_.vfov_min_deg) /
                                               (config_.channels - 1));
}

double LidarRenderer::azimuth_rad(int sample) const {
  const double span = config_.hfov_max_deg - config_.hfov_min_deg;
  const bool full = span >= 360.0 - 1e-9;
  const double step =
      full || config_.samples == 1 ? span / config_.samples : span / (config_.samples - 1);
  return deg_to_rad(config_.hfov_min_deg + sample * step);
}

void LidarRenderer::render(const Scene& scene, const Pose& pose, std::vector<BeamReturn>& out,
                           int hidden_vehicle_slot) {
  if (!scene.committed()) throw std::logic_error("lidar render: scene not committed");
  const int sub = config_.beam_samples;
  const int rays_per_sample = config_.channels * sub;
  const RayFrame frame(pose);
  const auto tnear = static_cast<float>(config_.min_range_m);
  const auto tfar = static_cast<float>(config_.max_range_m);
  RTCScene handle = scene.handle();
  // Packets of 16 consecutive beams: measured ~10 % faster than single rays for a VLP-16.
  constexpr bool packets = true;
  const int tasks = (config_.samples + kSamplesPerTask - 1) / kSamplesPerTask;
  pool_.run(tasks, [&](int task) {
    const int s0 = task * kSamplesPerTask, s1 = std::min(config_.samples, s0 + kSamplesPerTask);
    const std::size_t r0 = static_cast<std::size_t>(s0) * rays_per_sample;
    const std::size_t r1 = static_cast<std::size_t>(s1) * rays_per_sample;
    HidingContext ctx;
    init_hiding_context(ctx, hidden_vehicle_slot, false);
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    float dir[16][3];
    for (std::size_t base = r0; base < r1; base += 16) {
      fill_packet(rh, valid, dir, base, r1, directions_.data(), frame, tnear, tfar);
      intersect(packets, valid, handle, &ctx.context, rh);
      for (int l = 0; l < 16; ++l) {
        if (!valid[l]) continue;
        const std::size_t r = base + static_cast<std::size_t>(l);
        if (rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) {
          hits_range_[r] = -1.0f;
          hits_intensity_[r] = 0.0f;
          continue;
        }
        const float n[3] = {rh.hit.Ng_x[l], rh.hit.Ng_y[l], rh.hit.Ng_z[l]};
        const float nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const float cosi =
            std::abs(n[0] * dir[l][0] + n[1] * dir[l][1] + n[2] * dir[l][2]) / std::max(nl, 1e-30f);
        const Surface& s = scene.surface(rh.hit.geomID[l]);
        const float refl = s.reflectance_of(rh.hit.primID[l]);
        hits_range_[r] = rh.ray.tfar[l];
        hits_intensity_[r] = refl * cosi;
      }
    }
    // Reduce sub-rays to one return per beam.
    for (int s = s0; s < s1; ++s) {
      for (int c = 0; c < config_.channels; ++c) {
        const std::size_t beam = static_cast<std::size_t>(s) * config_.channels + c;
        const std::size_t first = beam * sub;
        BeamReturn ret;
        if (sub == 1) {
          ret = {hits_range_[first], hits_intensity_[first]};
        } else {
          int hits = 0;
          float sum_range = 0.0f, sum_intensity = 0.0f;
          float best_range = std::numeric_limits<float>::infinity(), best_intensity = -1.0f;
          float nearest_intensity = 0.0f, strongest_range = 0.0f;
          for (int j = 0; j < sub; ++j) {
            const float rr = hits_range_[first + j], ii = hits_intensity_[first + j];
            if (rr <= 0.0f) continue;
            ++hits;
            sum_range += rr;
            sum_intensity += ii;
            if (rr < best_range) {
              best_range = rr;
              nearest_intensity = ii;
            }
            if (ii > best_intensity) {
              best_intensity = ii;
              strongest_range = rr;
            }
          }
          if (hits == 0) {
            ret = {-1.0f, 0.0f};
          } else {
            switch (config_.return_mode) {
              case LidarReturnMode::nearest:
                ret = {best_range, nearest_intensity};
                break;
              case LidarReturnMode::strongest:
                ret = {strongest_range, best_intensity};
                break;
              case LidarReturnMode::mean:
                ret = {sum_range / static_cast<float>(hits),
                       sum_intensity / static_cast<float>(sub)};
                break;
            }
          }
        }
        out[beam] = ret;
      }
    }
  });
}

LidarSensor::LidarSensor(const LidarConfig& config, std::string vehicle_id, std::uint64_t seed,
                         double tick_s)
    : config_(config),
      vehicle_id_(std::move(vehicle_id)),
      seed_(seed),
      renderer_(config),
      clock_(config.rate_hz, config.lag_s, tick_s, config.id) {
  returns_.resize(static_cast<std::size_t>(renderer_.beams()));
  points_.resize(returns_.size());
}

Pose LidarSensor::sensor_pose(const Scene& scene) const {
  return mounted_pose(scene, vehicle_id_, config_.mount.pose, config_.id);
}

namespace {
// sin and cos of a small noise angle: series to d^5 (error < 2e-9 for |d| < 0.1).
void small_sincos(double d, double& s, double& c) {
  if (std::abs(d) < 0.1) {
    const double d2 = d * d;
    s = d * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0));
    c = 1.0 - d2 / 2.0 * (1.0 - d2 / 12.0);
  } else {
    s = std::sin(d);
    c = std::cos(d);
  }
}
}  // namespace

LidarScan LidarSensor::scan(const Scene& scene, std::uint64_t noise_index) {
  LidarScan out;
  out.sensor_id = config_.id;
  out.pose = sensor_pose(scene);
  out.channels = config_.channels;
  out.samples = config_.samples;
  const int hidden =
      config_.hide_own_vehicle && !vehicle_id_.empty() ? scene.vehicle_slot(vehicle_id_) : -1;
  renderer_.render(scene, out.pose, returns_, hidden);
  // Noise is a pure function of (seed, scan, beam): three normals from one 64-bit hash, so the
  // result does not depend on how beams are spread over threads.
  const std::uint64_t scan_key = mix64(seed_ ^ mix64(noise_index + 0x11DA));
  const NormalTable& normal = NormalTable::instance();
  const double sr = config_.range_noise_std_m, sa = config_.angle_noise_std_rad;
  const int channels = config_.channels;
  const int tasks = (config_.samples + kSamplesPerTask - 1) / kSamplesPerTask;
  renderer_.pool().run(tasks, [&](int task) {
    const int s0 = task * kSamplesPerTask, s1 = std::min(config_.samples, s0 + kSamplesPerTask);
    for (int s = s0; s < s1; ++s) {
      for (int c = 0; c < channels; ++c) {
        const std::size_t beam = static_cast<std::size_t>(s) * channels + c;
        const BeamReturn& r = returns_[beam];
        LidarPoint& p = points_[beam];
        if (r.range <= 0.0f) {
          p.range = -1.0f;
          continue;
        }
        const std::uint64_t h = mix64(scan_key + beam);
        const double range = r.range + sr * normal(static_cast<std::uint32_t>(h));
        double ca = renderer_.cos_azimuth(s), sa_ = renderer_.sin_azimuth(s);
        double ce = renderer_.cos_elevation(c), se = renderer_.sin_elevation(c);
        if (sa > 0.0) {
          double sd, cd;
          small_sincos(sa * normal(static_cast<std::uint32_t>(h >> 16)), sd, cd);
          const double ca2 = ca * cd - sa_ * sd, sa2 = sa_ * cd + ca * sd;
          small_sincos(sa * normal(static_cast<std::uint32_t>(h >> 32)), sd, cd);
          const double ce2 = ce * cd - se * sd, se2 = se * cd + ce * sd;
          ca = ca2;
          sa_ = sa2;
          ce = ce2;
          se = se2;
        }
        p.x = static_cast<float>(range * ce * ca);
        p.y = static_cast<float>(range * ce * sa_);
        p.z = static_cast<float>(range * se);
        p.range = static_cast<float>(range);
        p.intensity = r.intensity;
        p.channel = static_cast<std::uint16_t>(c);
        p.sample = static_cast<std::uint16_t>(s);
      }
    }
  });
  std::size_t count = 0;
  for (const auto& r : returns_) count += r.range > 0.0f;
  out.points.reserve(count);
  for (std::size_t b = 0; b < returns_.size(); ++b) {
    if (returns_[b].range > 0.0f) out.points.push_back(points_[b]);
  }
  return out;
}

void LidarSensor::update(const Scene& scene, double time_s) {
  const std::int64_t tick = clock_.tick_of(time_s);
  if (const auto k = clock_.trigger(tick)) {
    LidarScan s = scan(scene, *k);
    s.stamp = clock_.stamp(*k, tick);
    queue_.push(std::move(s), tick + clock_.lag_ticks());
  }
}

std::vector<LidarScan> LidarSensor::take_available(double now_s) {
  return queue_.take_ready(clock_.tick_of(now_s));
}

// Kept: the clock and the waiting scans. Not kept: returns_ and points_ (work arrays of one
// scan) and the renderer (configuration).
void LidarSensor::save_state(core::StateWriter& w) const {
  w.begin("lidar", 1);
  w.io(seed_);
  clock_.save_state(w);
  queue_.save_state(w, [](core::StateWriter& ww, const LidarScan& s) {
    ww.io(s.sensor_id);
    ww.io(s.stamp);
    ww.io(s.pose.position);
    ww.io(s.pose.orientation);
    ww.io(s.channels);
    ww.io(s.samples);
    ww.io(static_cast<std::uint64_t>(s.points.size()));
    for (const LidarPoint& p : s.points) {
      ww.io(p.x);
      ww.io(p.y);
      ww.io(p.z);
      ww.io(p.intensity);
      ww.io(p.range);
      ww.io(p.channel);
      ww.io(p.sample);
    }
  });
  w.end();
}

void LidarSensor::load_state(core::StateReader& r) {
  r.begin("lidar", 1);
  if (r.get<std::uint64_t>() != seed_) {
    r.fail(config_.id + ": the state is of a lidar with another noise seed (another scenario "
           "seed or vehicle)");
  }
  clock_.load_state(r, config_.id);
  queue_.load_state(r, [](core::StateReader& rr, LidarScan& s) {
    rr.io(s.sensor_id);
    rr.io(s.stamp);
    rr.io(s.pose.position);
    rr.io(s.pose.orientation);
    rr.io(s.channels);
    rr.io(s.samples);
    const auto n = rr.get<std::uint64_t>();
    s.points.clear();
    for (std::uint64_t k = 0; k < n; ++k) {
      LidarPoint p;
      rr.io(p.x);
      rr.io(p.y);
      rr.io(p.z);
      rr.io(p.intensity);
      rr.io(p.range);
      rr.io(p.channel);
      rr.io(p.sample);
      s.points.push_back(p);
    }
  });
  r.end();
}

}  // namespace syndds::sensors
