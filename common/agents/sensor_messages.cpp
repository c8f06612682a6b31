#include "agents/sensor_messages.hpp"

namespace syndds::agents {
namespace {

template <typename Msg, typename Sample>
Msg header(const Sample& s, const std::string& vehicle_id, const std::string& source,
           std::int64_t frame) {
  Msg m;
  m.vehicle_id = vehicle_id;
  m.source = source;
  m.frame = frame;
  m.stamp = {s.sensor_id, s.stamp.sequence, s.stamp.time_s, s.stamp.available_s};
  return m;
}

}  // namespace

void append_messages(const sensors::InteroceptiveBatch& batch, const std::string& vehicle_id,
                     const std::string& source, std::int64_t frame, proto::FrameSamples& out) {
  for (const auto& s : batch.gps) {
    auto m = header<proto::GpsFixMsg>(s, vehicle_id, source, frame);
    m.latitude_deg = s.position.lat_deg;
    m.longitude_deg = s.position.lon_deg;
    m.altitude_m = s.position.alt_m;
    m.enu_m = s.enu_m;
    out.gps_fixes.push_back(std::move(m));
  }
  for (const auto& s : batch.imu) {
    auto m = header<proto::ImuMsg>(s, vehicle_id, source, frame);
    m.accel_mps2 = s.accel_mps2;
    m.gyro_rad_s = s.gyro_rad_s;
    out.imus.push_back(std::move(m));
  }
  for (const auto& s : batch.magnetometer) {
    auto m = header<proto::MagnetometerMsg>(s, vehicle_id, source, frame);
    m.heading_rad = s.heading_rad;
    m.field_ut = s.field_ut;
    out.magnetometers.push_back(std::move(m));
  }
  for (const auto& s : batch.tachometer) {
    auto m = header<proto::WheelSpeedsMsg>(s, vehicle_id, source, frame);
    m.wheel_spin_rad_s = s.wheel_spin_rad_s;
    out.wheel_speeds.push_back(std::move(m));
  }
}

void append_messages(const sensors::RenderedBatch& batch, const std::string& vehicle_id,
                     const std::string& source, std::int64_t frame, proto::FrameSamples& out) {
  for (const auto& f : batch.camera) {
    auto m = header<proto::ImageMsg>(f, vehicle_id, source, frame);
    m.pose = f.pose;
    m.width = f.image.width;
    m.height = f.image.height;
    m.encoding = "rgb8";
    m.data = f.image.pixels;
    out.images.push_back(std::move(m));
  }
  for (const auto& scan : batch.lidar) {
    auto m = header<proto::PointCloudMsg>(scan, vehicle_id, source, frame);
    m.pose = scan.pose;
    m.channels = scan.channels;
    m.samples = scan.samples;
    m.points.reserve(scan.points.size());
    for (const auto& p : scan.points) {
      m.points.push_back({p.x, p.y, p.z, p.intensity, p.range, p.channel, p.sample});
    }
    out.point_clouds.push_back(std::move(m));
  }
  for (const auto& scan : batch.radar) {
    auto m = header<proto::RadarScanMsg>(scan, vehicle_id, source, frame);
    m.pose = scan.pose;
    m.velocity = scan.velocity;
    m.detections.reserve(scan.detections.size());
    for (const auto& d : scan.detections) {
      m.detections.push_back({d.x, d.y, d.z, d.range_m, d.azimuth_rad, d.elevation_rad,
                              d.radial_speed_mps, d.strength_db, d.rcs_dbsm, d.points});
    }
    out.radar_scans.push_back(std::move(m));
  }
}

}  // namespace syndds::agents
