#include "sensors/camera.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/state_io.hpp"
#include "sensors/random.hpp"
#include "sensors/ray_packets.hpp"

namespace syndds::sensors {
namespace {

constexpr int kTile = 16;       // pixels per tile side
constexpr int kPacketSide = 4;  // 4 x 4 pixels per 16-ray packet
constexpr float kShadowOffset = 2e-3f;
// Below this focal length (pixels per radian; 80 px over 90 deg gives 40) neighbouring rays
// diverge too much for packet traversal to pay off.
constexpr double kPacketMinFocalPx = 150.0;

// Radius r with r (1 + k1 r^2 + k2 r^4) = rd (Newton from r = rd).
double undistort_radius(double rd, double k1, double k2) {
  double r = rd;
  for (int i = 0; i < 12; ++i) {
    const double r2 = r * r;
    const double g = r * (1.0 + k1 * r2 + k2 * r2 * r2) - rd;
    const double dg = 1.0 + 3.0 * k1 * r2 + 5.0 * k2 * r2 * r2;
    const double step = g / dg;
    r -= step;
    if (std::abs(step) < 1e-14) break;
  }
  return r;
}

}  // namespace

CameraModel::CameraModel(const CameraIntrinsics& intrinsics) : intrinsics_(intrinsics) {
  if (intrinsics.width < 16 || intrinsics.height < 9 || intrinsics.width > 7680 ||
      intrinsics.height > 4320) {
    throw std::invalid_argument("camera resolution must be within 16x9 .. 7680x4320");
  }
  if (!(intrinsics.hfov_rad > 0.0) || intrinsics.hfov_rad >= deg_to_rad(170.0)) {
    throw std::invalid_argument("camera hfov must be in (0, 170) degrees");
  }
  focal_ = 0.5 * intrinsics.width / std::tan(0.5 * intrinsics.hfov_rad);
  // Distortion must stay monotonic over the image (else the inverse is ambiguous).
  const double half_diag = 0.5 * std::hypot(intrinsics.width, intrinsics.height) / focal_ * 1.5;
  for (int i = 1; i <= 100; ++i) {
    const double r = half_diag * i / 100.0, r2 = r * r;
    if (1.0 + 3.0 * intrinsics.k1 * r2 + 5.0 * intrinsics.k2 * r2 * r2 <= 0.0) {
      throw std::invalid_argument("camera distortion (k1, k2) folds the image over");
    }
  }
}

std::optional<Vec2> CameraModel::project(const Vec3& p) const {
  if (p.x() <= 1e-9) return std::nullopt;
  const double xn = -p.y() / p.x(), yn = -p.z() / p.x();
  const double r2 = xn * xn + yn * yn;
  const double s = 1.0 + intrinsics_.k1 * r2 + intrinsics_.k2 * r2 * r2;
  return Vec2(focal_ * xn * s + 0.5 * intrinsics_.width,
              focal_ * yn * s + 0.5 * intrinsics_.height);
}

Vec3 CameraModel::ray_direction(double u, double v) const {
  double xd = (u - 0.5 * intrinsics_.width) / focal_;
  double yd = (v - 0.5 * intrinsics_.height) / focal_;
  if (intrinsics_.k1 != 0.0 || intrinsics_.k2 != 0.0) {
    const double rd = std::hypot(xd, yd);
    if (rd > 1e-12) {
      const double s = undistort_radius(rd, intrinsics_.k1, intrinsics_.k2) / rd;
      xd *= s;
      yd *= s;
    }
  }
  return Vec3(1.0, -xd, -yd).normalized();
}

CameraRenderer::CameraRenderer(const CameraIntrinsics& intrinsics, int threads)
    : model_(intrinsics), pool_(threads) {}

void CameraRenderer::render(const Scene& scene, const Pose& pose, std::span<float> radiance,
                            int hidden_vehicle_slot) {
  if (!scene.committed()) throw std::logic_error("camera render: scene not committed");
  const int width = model_.intrinsics().width, height = model_.intrinsics().height;
  if (radiance.size() != static_cast<std::size_t>(width) * height * 3) {
    throw std::invalid_argument("camera render: radiance buffer has the wrong size");
  }
  const RayFrame frame(pose);
  const SceneConfig& sc = scene.config();
  const Vec3 sun_d = sc.sun_direction();
  const float sun[3] = {static_cast<float>(sun_d.x()), static_cast<float>(sun_d.y()),
                        static_cast<float>(sun_d.z())};
  const float sun_i = sc.sun_intensity, amb_i = sc.ambient_intensity, bounce = sc.ground_bounce;
  const float shadow_far = std::isfinite(sc.shadow_max_distance_m)
                               ? static_cast<float>(sc.shadow_max_distance_m)
                               : std::numeric_limits<float>::infinity();
  const bool distorted = model_.intrinsics().k1 != 0.0 || model_.intrinsics().k2 != 0.0;
  const float f = static_cast<float>(model_.focal_px());
  const float cx = 0.5f * static_cast<float>(width), cy = 0.5f * static_cast<float>(height);
  const int tiles_x = (width + kTile - 1) / kTile, tiles_y = (height + kTile - 1) / kTile;
  RTCScene handle = scene.handle();
  const bool packets = model_.focal_px() >= kPacketMinFocalPx;

  pool_.run(tiles_x * tiles_y, [&](int tile) {
    const int x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;
    HidingContext primary_ctx, shadow_ctx;
    init_hiding_context(primary_ctx, hidden_vehicle_slot, true);
    init_hiding_context(shadow_ctx, -1, true);
    alignas(64) RTCRayHit16 rh;
    alignas(64) RTCRay16 sr;
    alignas(64) int valid[16];
    alignas(64) int shadow_valid[16];
    float dir[16][3];
    float albedo[16][3];
    float light[16];
    float ambient[16];
    for (int by = 0; by < kTile; by += kPacketSide) {
      for (int bx = 0; bx < kTile; bx += kPacketSide) {
        bool any = false;
        for (int l = 0; l < 16; ++l) {
          const int u = x0 + bx + (l & 3), v = y0 + by + (l >> 2);
          valid[l] = (u < width && v < height) ? -1 : 0;
          if (!valid[l]) continue;
          any = true;
          float d[3];
          if (distorted) {
            const Vec3 dc = model_.ray_direction(u + 0.5, v + 0.5);
            d[0] = static_cast<float>(dc.x());
            d[1] = static_cast<float>(dc.y());
            d[2] = static_cast<float>(dc.z());
          } else {
            d[0] = 1.0f;
            d[1] = -((static_cast<float>(u) + 0.5f - cx) / f);
            d[2] = -((static_cast<float>(v) + 0.5f - cy) / f);
          }
          float w[3];
          for (int i = 0; i < 3; ++i) {
            w[i] = frame.m[3 * i] * d[0] + frame.m[3 * i + 1] * d[1] + frame.m[3 * i + 2] * d[2];
          }
          const float inv = 1.0f / std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
          for (int i = 0; i < 3; ++i) dir[l][i] = w[i] * inv;
          rh.ray.org_x[l] = frame.o[0];
          rh.ray.org_y[l] = frame.o[1];
          rh.ray.org_z[l] = frame.o[2];
          rh.ray.dir_x[l] = dir[l][0];
          rh.ray.dir_y[l] = dir[l][1];
          rh.ray.dir_z[l] = dir[l][2];
          rh.ray.tnear[l] = 0.0f;
          rh.ray.tfar[l] = std::numeric_limits<float>::infinity();
          rh.ray.time[l] = 0.0f;
          rh.ray.mask[l] = 0xFFFFFFFFu;
          rh.ray.id[l] = static_cast<unsigned>(l);
          rh.ray.flags[l] = 0;
          rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
          rh.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
        }
        if (!any) continue;
        intersect(packets, valid, handle, &primary_ctx.context, rh);
        bool any_shadow = false;
        for (int l = 0; l < 16; ++l) {
          shadow_valid[l] = 0;
          if (!valid[l]) continue;
          if (rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) {
            const float t = std::clamp(dir[l][2], 0.0f, 1.0f);
            albedo[l][0] = sc.sky_horizon.r + t * (sc.sky_zenith.r - sc.sky_horizon.r);
            albedo[l][1] = sc.sky_horizon.g + t * (sc.sky_zenith.g - sc.sky_horizon.g);
            albedo[l][2] = sc.sky_horizon.b + t * (sc.sky_zenith.b - sc.sky_horizon.b);
            light[l] = 0.0f;
            ambient[l] = 1.0f;  // sky radiance as is
            continue;
          }
          float n[3] = {rh.hit.Ng_x[l], rh.hit.Ng_y[l], rh.hit.Ng_z[l]};
          const float nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
          const float sign =
              (n[0] * dir[l][0] + n[1] * dir[l][1] + n[2] * dir[l][2]) > 0.0f ? -1.0f : 1.0f;
          for (float& c : n) c *= sign / nl;
          const float t = rh.ray.tfar[l];
          const float p[3] = {frame.o[0] + t * dir[l][0], frame.o[1] + t * dir[l][1],
                              frame.o[2] + t * dir[l][2]};
          const Surface& s = scene.surface(rh.hit.geomID[l]);
          const Rgb a = s.kind == SurfaceKind::terrain ? scene.terrain_albedo(p[0], p[1])
                                                       : s.colour_of(rh.hit.primID[l]);
          albedo[l][0] = a.r;
          albedo[l][1] = a.g;
          albedo[l][2] = a.b;
          ambient[l] = amb_i * ((0.5f + 0.5f * n[2]) + bounce * (0.5f - 0.5f * n[2]));
          const float ndotl = n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2];
          light[l] = ndotl > 0.0f ? sun_i * ndotl : 0.0f;
          if (ndotl > 0.0f) {
            shadow_valid[l] = -1;
            any_shadow = true;
            sr.org_x[l] = p[0] + kShadowOffset * n[0];
            sr.org_y[l] = p[1] + kShadowOffset * n[1];
            sr.org_z[l] = p[2] + kShadowOffset * n[2];
            sr.dir_x[l] = sun[0];
            sr.dir_y[l] = sun[1];
            sr.dir_z[l] = sun[2];
            sr.tnear[l] = 0.0f;
            sr.tfar[l] = shadow_far;
            sr.time[l] = 0.0f;
            sr.mask[l] = 0xFFFFFFFFu;
            sr.id[l] = static_cast<unsigned>(l);
            sr.flags[l] = 0;
          }
        }
        if (any_shadow) occluded(packets, shadow_valid, handle, &shadow_ctx.context, sr);
        for (int l = 0; l < 16; ++l) {
          if (!valid[l]) continue;
          const float direct = (shadow_valid[l] && sr.tfar[l] >= 0.0f) ? light[l] : 0.0f;
          const float e = direct + ambient[l];
          const int u = x0 + bx + (l & 3), v = y0 + by + (l >> 2);
          float* o = &radiance[(static_cast<std::size_t>(v) * width + u) * 3];
          o[0] = albedo[l][0] * e;
          o[1] = albedo[l][1] * e;
          o[2] = albedo[l][2] * e;
        }
      }
    }
  });
}

Pose chase_camera_pose(const Pose& vehicle, const ChaseConfig& chase) {
  // The horizontal direction the camera looks along: the vehicle's heading turned by the
  // azimuth towards its right, so that the camera, behind the vehicle along it, has swung
  // towards the vehicle's left (azimuth 0: the heading itself, bit for bit).
  const double heading = yaw_of(vehicle.orientation) - deg_to_rad(chase.azimuth_deg);
  const Vec3 view(std::cos(heading), std::sin(heading), 0.0);
  Pose p;
  p.position = vehicle.position - chase.distance_m * view + Vec3(0, 0, chase.height_m);
  const Vec3 target = vehicle.position + Vec3(0, 0, chase.target_height_m);
  Vec3 x = target - p.position;
  if (x.norm() < 1e-9) x = view;
  x.normalize();
  Vec3 y = Vec3::UnitZ().cross(x);
  if (y.norm() < 1e-9) y = Vec3(-view.y(), view.x(), 0.0);
  y.normalize();
  const Vec3 z = x.cross(y);
  Eigen::Matrix3d r;
  r.col(0) = x;
  r.col(1) = y;
  r.col(2) = z;
  p.orientation = Quat(r);
  return p;
}

namespace {
std::vector<std::pair<std::int64_t, int>> exposure_offsets(const CameraConfig& c, double tick_s) {
  std::vector<double> instants;
  switch (c.exposure_mode) {
    case ExposureMode::instant:
      instants = {0.0};
      break;
    case ExposureMode::midpoint:
      instants = {0.5 * c.exposure_s};
      break;
    case ExposureMode::average:
      for (int i = 0; i < c.subframes; ++i)
        instants.push_back(c.exposure_s * (i + 0.5) / c.subframes);
      break;
  }
  std::vector<std::pair<std::int64_t, int>> out;
  for (double t : instants) {
    // Nearest tick, ties upwards (robust to 0.49999... from floating point).
    const auto off = static_cast<std::int64_t>(std::floor(t / tick_s + 0.5 + 1e-7));
    if (!out.empty() && out.back().first == off) {
      ++out.back().second;
    } else {
      out.emplace_back(off, 1);
    }
  }
  return out;
}
}  // namespace

CameraSensor::CameraSensor(const CameraConfig& config, std::string vehicle_id, std::uint64_t seed,
                           double tick_s)
    : config_(config),
      vehicle_id_(std::move(vehicle_id)),
      seed_(seed),
      renderer_(config.intrinsics, config.threads),
      clock_(config.rate_hz, config.lag_s, tick_s, config.id) {
  if (config.exposure_mode == ExposureMode::average && config.subframes < 1) {
    throw std::invalid_argument(config.id + ": subframes must be >= 1");
  }
  if (config.exposure_s < 0.0) throw std::invalid_argument(config.id + ": exposure_s must be >= 0");
  if (config.mode != CameraMode::fixed && vehicle_id_.empty()) {
    throw std::invalid_argument(config.id + ": a mounted or chase camera needs a vehicle id");
  }
  if (!(config.gamma > 0.0)) throw std::invalid_argument(config.id + ": gamma must be > 0");
  offsets_ = exposure_offsets(config, tick_s);
  const std::int64_t last = offsets_.back().first;
  if (static_cast<double>(last) > std::floor(clock_.period_ticks() + 1e-7)) {
    throw std::invalid_argument(config.id + ": exposure window longer than the frame period");
  }
  if (last > clock_.lag_ticks()) {
    throw std::invalid_argument(config.id + ": lag must cover the exposure window");
  }
  const std::size_t n = static_cast<std::size_t>(config.intrinsics.width) *
                        static_cast<std::size_t>(config.intrinsics.height) * 3;
  frame_radiance_.resize(n);
  if (offsets_.size() > 1) accum_.resize(n);
  gamma_lut_.resize(4097);
  for (std::size_t i = 0; i < gamma_lut_.size(); ++i) {
    gamma_lut_[i] =
        static_cast<float>(std::pow(static_cast<double>(i) / 4096.0, 1.0 / config.gamma));
  }
}

int CameraSensor::hidden_slot(const Scene& scene) const {
  if (config_.mode != CameraMode::mounted || !config_.hide_own_vehicle) return -1;
  return scene.vehicle_slot(vehicle_id_);
}

Pose CameraSensor::camera_pose(const Scene& scene) const {
  if (config_.mode == CameraMode::fixed) return config_.mount.pose;
  const auto vehicle = scene.vehicle_pose(vehicle_id_);
  if (!vehicle)
    throw std::runtime_error(config_.id + ": vehicle '" + vehicle_id_ + "' not in scene");
  if (config_.mode == CameraMode::chase) return chase_camera_pose(*vehicle, config_.chase);
  Pose p;
  p.position = vehicle->position + vehicle->orientation * config_.mount.pose.position;
  p.orientation = vehicle->orientation * config_.mount.pose.orientation;
  return p;
}

RgbImage CameraSensor::finish(std::span<const float> radiance, std::uint64_t noise_index) {
  const int width = config_.intrinsics.width, height = config_.intrinsics.height;
  RgbImage img;
  img.width = width;
  img.height = height;
  img.pixels.resize(static_cast<std::size_t>(width) * height * 3);
  const std::uint64_t frame_key = mix64(seed_ ^ mix64(noise_index + 0x5EED));
  const NormalTable& normal = NormalTable::instance();
  const float gain = static_cast<float>(config_.gain);
  const auto model = config_.noise;
  const float std_dev = static_cast<float>(config_.noise_std);
  const float slope = static_cast<float>(config_.noise_slope);
  const float intercept = static_cast<float>(config_.noise_intercept);
  constexpr int kRows = 16;
  const int blocks = (height + kRows - 1) / kRows;
  renderer_.pool().run(blocks, [&](int block) {
    const int v0 = block * kRows, v1 = std::min(height, v0 + kRows);
    for (std::size_t i = static_cast<std::size_t>(v0) * width * 3;
         i < static_cast<std::size_t>(v1) * width * 3; ++i) {
      const float x = std::clamp(gain * radiance[i], 0.0f, 1.0f) * 4096.0f;
      const auto k = static_cast<std::size_t>(x);
      float v = k >= 4096 ? gamma_lut_[4096]
                          : gamma_lut_[k] +
                                (x - static_cast<float>(k)) * (gamma_lut_[k + 1] - gamma_lut_[k]);
      if (model != PixelNoiseModel::none) {
        const float sigma = model == PixelNoiseModel::gaussian
                                ? std_dev
                                : std::sqrt(std::max(0.0f, slope * v + intercept));
        v += sigma * normal(static_cast<std::uint32_t>(mix64(frame_key + i) >> 48));
      }
      img.pixels[i] = static_cast<std::uint8_t>(std::clamp(v, 0.0f, 1.0f) * 255.0f + 0.5f);
    }
  });
  return img;
}

RgbImage CameraSensor::capture(const Scene& scene, std::uint64_t noise_index) {
  last_pose_ = camera_pose(scene);
  renderer_.render(scene, last_pose_, frame_radiance_, hidden_slot(scene));
  ++renders_;
  return finish(frame_radiance_, noise_index);
}

void CameraSensor::advance(const Scene& scene, std::int64_t tick) {
  if (!capture_) return;
  Capture& c = *capture_;
  bool rendered = false;
  while (c.next < offsets_.size() && c.trigger_tick + offsets_[c.next].first <= tick) {
    if (!rendered) {
      last_pose_ = camera_pose(scene);
      renderer_.render(scene, last_pose_, frame_radiance_, hidden_slot(scene));
      ++renders_;
      rendered = true;
    }
    const auto w = static_cast<float>(offsets_[c.next].second);
    if (offsets_.size() == 1) {
      // One render instant: the image is that render (no accumulation pass).
    } else if (c.weight == 0.0) {
      for (std::size_t i = 0; i < accum_.size(); ++i) accum_[i] = w * frame_radiance_[i];
    } else {
      for (std::size_t i = 0; i < accum_.size(); ++i) accum_[i] += w * frame_radiance_[i];
    }
    c.weight += w;
    ++c.next;
  }
  if (c.next < offsets_.size()) return;
  CameraFrame frame;
  frame.sensor_id = config_.id;
  frame.stamp = clock_.stamp(c.k, c.trigger_tick);
  frame.pose = last_pose_;
  if (offsets_.size() == 1) {
    frame.image = finish(frame_radiance_, c.k);
  } else {
    const auto inv = static_cast<float>(1.0 / c.weight);
    for (float& a : accum_) a *= inv;
    frame.image = finish(accum_, c.k);
  }
  queue_.push(std::move(frame), c.trigger_tick + clock_.lag_ticks());
  capture_.reset();
}

void CameraSensor::update(const Scene& scene, double time_s) {
  const std::int64_t tick = clock_.tick_of(time_s);
  advance(scene, tick);
  if (const auto k = clock_.trigger(tick)) {
    if (filter_ && !filter_(tick + clock_.lag_ticks(),
                            clock_.trigger_tick(*k + 1) + clock_.lag_ticks())) {
      ++skipped_;
      return;
    }
    if (capture_) throw std::logic_error(config_.id + ": capture still open");
    capture_ = Capture{*k, tick, 0, 0.0};
    advance(scene, tick);
  }
}

bool CameraSensor::may_render(double time_s) const {
  const std::int64_t tick = clock_.tick_of(time_s);
  // The open exposure's next instant has come (advance() renders it).
  if (capture_ && capture_->trigger_tick + offsets_[capture_->next].first <= tick) return true;
  if (!clock_.due(tick)) return false;
  // A frame triggered now renders now only if its exposure starts at the trigger (midpoint and
  // average exposures start later: their renders come in later ticks).
  if (offsets_.front().first > 0) return false;
  if (!filter_) return true;
  // The frame due (the clock has started once a frame was triggered; before, assume it may).
  const std::uint64_t k = clock_.next_index();
  return filter_(tick + clock_.lag_ticks(), clock_.trigger_tick(k + 1) + clock_.lag_ticks());
}

std::vector<CameraFrame> CameraSensor::take_available(double now_s) {
  return queue_.take_ready(clock_.tick_of(now_s));
}

// Kept: the clock, the open capture and, once it has accumulated a render, accum_ (the next
// frames add to it); last_pose_ (the frame's pose is that of its last render); renders_; the
// waiting frames. Not kept: frame_radiance_ (rendered and used within one update), the pixel
// noise (a pure function of seed and frame index), offsets_ and gamma_lut_ (configuration).
void CameraSensor::save_state(core::StateWriter& w) const {
  w.begin("camera", 1);
  w.io(seed_);
  clock_.save_state(w);
  w.io(capture_.has_value());
  if (capture_) {
    w.io(capture_->k);
    w.io(capture_->trigger_tick);
    w.io(static_cast<std::uint64_t>(capture_->next));
    w.io(capture_->weight);
    if (offsets_.size() > 1 && capture_->weight != 0.0) w.io(accum_);
  }
  w.io(last_pose_.position);
  w.io(last_pose_.orientation);
  w.io(static_cast<std::uint64_t>(renders_));
  queue_.save_state(w, [](core::StateWriter& ww, const CameraFrame& f) {
    ww.io(f.sensor_id);
    ww.io(f.stamp);
    ww.io(f.pose.position);
    ww.io(f.pose.orientation);
    ww.io(f.image.width);
    ww.io(f.image.height);
    ww.io(f.image.pixels);
  });
  w.end();
}

void CameraSensor::load_state(core::StateReader& r) {
  r.begin("camera", 1);
  if (r.get<std::uint64_t>() != seed_) {
    r.fail(config_.id + ": the state is of a camera with another noise seed (another scenario "
           "seed or vehicle)");
  }
  clock_.load_state(r, config_.id);
  capture_.reset();
  if (r.get<bool>()) {
    Capture c;
    r.io(c.k);
    r.io(c.trigger_tick);
    c.next = static_cast<std::size_t>(r.get<std::uint64_t>());
    r.io(c.weight);
    if (c.next > offsets_.size()) r.fail(config_.id + ": the open exposure is past its end");
    if (offsets_.size() > 1 && c.weight != 0.0) {
      std::vector<float> accum;
      r.io(accum);
      if (accum.size() != accum_.size()) {
        r.fail(config_.id + ": the open exposure holds " + std::to_string(accum.size()) +
               " radiance values, this camera " + std::to_string(accum_.size()) +
               " (another image size)");
      }
      accum_ = std::move(accum);
    }
    capture_ = c;
  }
  r.io(last_pose_.position);
  r.io(last_pose_.orientation);
  renders_ = static_cast<std::size_t>(r.get<std::uint64_t>());
  queue_.load_state(r, [](core::StateReader& rr, CameraFrame& f) {
    rr.io(f.sensor_id);
    rr.io(f.stamp);
    rr.io(f.pose.position);
    rr.io(f.pose.orientation);
    rr.io(f.image.width);
    rr.io(f.image.height);
    rr.io(f.image.pixels);
  });
  r.end();
}

}  // namespace syndds::sensors
