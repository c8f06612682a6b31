#include "dds/convert.hpp"

#include <cmath>

#include "core/error.hpp"

namespace syndds::dds {
namespace {

msg::Vec3 v3(const Vec3& v) {
  msg::Vec3 o;
  o.x(v.x());
  o.y(v.y());
  o.z(v.z());
  return o;
}
Vec3 v3(const msg::Vec3& v) { return Vec3(v.x(), v.y(), v.z()); }

msg::Pose pose(const Pose& p) {
  msg::Pose o;
  o.position(v3(p.position));
  msg::Quat q;
  q.w(p.orientation.w());
  q.x(p.orientation.x());
  q.y(p.orientation.y());
  q.z(p.orientation.z());
  o.orientation(q);
  return o;
}
Pose pose(const msg::Pose& p) {
  Pose o;
  o.position = v3(p.position());
  const auto& q = p.orientation();
  o.orientation = Quat(q.w(), q.x(), q.y(), q.z());
  return o;
}

std::vector<msg::TopicCount> manifest(const proto::Manifest& m) {
  std::vector<msg::TopicCount> out;
  out.reserve(m.size());
  for (const auto& e : m) {
    msg::TopicCount c;
    c.topic(std::string(proto::to_string(e.topic)));
    c.key(e.key);
    c.writer(e.writer);
    c.count(e.count);
    out.push_back(std::move(c));
  }
  return out;
}
proto::Manifest manifest(const std::vector<msg::TopicCount>& m) {
  proto::Manifest out;
  out.reserve(m.size());
  for (const auto& c : m) {
    proto::TopicCount e;
    if (!proto::topic_from_string(c.topic(), e.topic)) {
      throw ProtocolError("manifest entry names unknown topic '" + c.topic() + "' (writer " +
                          c.writer() + ")");
    }
    e.key = c.key();
    e.writer = c.writer();
    e.count = c.count();
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<msg::TerrainVertex> vertices(const std::vector<proto::TerrainVertexMsg>& in) {
  std::vector<msg::TerrainVertex> out;
  out.reserve(in.size());
  for (const auto& v : in) {
    msg::TerrainVertex x;
    x.i(v.i);
    x.j(v.j);
    x.height(v.height);
    x.level_initial(v.level_initial);
    x.sinkage_plastic(v.sinkage_plastic);
    x.sigma_yield(v.sigma_yield);
    out.push_back(x);
  }
  return out;
}

// Validated: every field finite, or ProtocolError naming the vertex and the field.
std::vector<proto::TerrainVertexMsg> vertices(const std::vector<msg::TerrainVertex>& in,
                                              const std::string& what) {
  std::vector<proto::TerrainVertexMsg> out;
  out.reserve(in.size());
  for (const auto& v : in) {
    for (const auto& [name, value] :
         {std::pair{"height", v.height()}, std::pair{"level_initial", v.level_initial()},
          std::pair{"sinkage_plastic", v.sinkage_plastic()},
          std::pair{"sigma_yield", v.sigma_yield()}}) {
      if (!std::isfinite(value)) {
        throw ProtocolError(what + ": vertex (" + std::to_string(v.i()) + ", " +
                            std::to_string(v.j()) + ") " + name + " is not finite");
      }
    }
    out.push_back(
        {v.i(), v.j(), v.height(), v.level_initial(), v.sinkage_plastic(), v.sigma_yield()});
  }
  return out;
}

msg::SensorStamp stamp(const proto::SensorStampMsg& s) {
  msg::SensorStamp o;
  o.sensor_id(s.sensor_id);
  o.number(s.sequence);
  o.time_s(s.time_s);
  o.available_s(s.available_s);
  return o;
}
proto::SensorStampMsg stamp(const msg::SensorStamp& s) {
  return {s.sensor_id(), s.number(), s.time_s(), s.available_s()};
}

// Common header of the sensor samples: key, writer, frame, stamp.
template <typename D, typename P>
void header_to(D& o, const P& m) {
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.stamp(stamp(m.stamp));
}
template <typename P, typename D>
void header_from(P& o, const D& m) {
  o.vehicle_id = m.vehicle_id();
  o.source = m.source();
  o.frame = m.frame();
  o.stamp = stamp(m.stamp());
}

}  // namespace

msg::MemberAnnounce to_dds(const proto::MemberAnnounceMsg& m) {
  msg::MemberAnnounce o;
  o.member_id(m.member_id);
  o.kind(static_cast<msg::MemberKind>(m.kind));
  o.run_id(m.run_id);
  o.participant_guid(m.participant_guid);
  o.host(m.host);
  o.pid(m.pid);
  o.protocol_version(m.protocol_version);
  o.config_fingerprint(m.config_fingerprint);
  o.expected_members(m.expected_members);
  return o;
}
proto::MemberAnnounceMsg from_dds(const msg::MemberAnnounce& m) {
  proto::MemberAnnounceMsg o;
  o.member_id = m.member_id();
  const auto kind = static_cast<int>(m.kind());
  if (kind < 0 || kind > static_cast<int>(proto::MemberKind::coordinator)) {
    throw ProtocolError("member_announce from '" + m.member_id() + "': kind " +
                        std::to_string(kind) + " is out of range");
  }
  o.kind = static_cast<proto::MemberKind>(kind);
  o.run_id = m.run_id();
  o.participant_guid = m.participant_guid();
  o.host = m.host();
  o.pid = m.pid();
  o.protocol_version = m.protocol_version();
  o.config_fingerprint = m.config_fingerprint();
  o.expected_members = m.expected_members();
  return o;
}

msg::FrameGrant to_dds(const proto::FrameGrantMsg& m) {
  msg::FrameGrant o;
  o.frame(m.frame);
  o.sim_time_s(m.sim_time_s);
  o.manifest(manifest(m.manifest));
  o.joiners(m.joiners);
  o.departed(m.departed);
  return o;
}
proto::FrameGrantMsg from_dds(const msg::FrameGrant& m) {
  return proto::FrameGrantMsg{m.frame(), m.sim_time_s(), manifest(m.manifest()), m.joiners(),
                              m.departed()};
}

msg::FrameDone to_dds(const proto::FrameDoneMsg& m) {
  msg::FrameDone o;
  o.member_id(m.member_id);
  o.frame(m.frame);
  o.published(manifest(m.published));
  o.compute_s(m.compute_s);
  o.finished(m.finished);
  o.error(m.error);
  return o;
}
proto::FrameDoneMsg from_dds(const msg::FrameDone& m) {
  return proto::FrameDoneMsg{m.member_id(), m.frame(),    manifest(m.published()),
                             m.compute_s(), m.finished(), m.error()};
}

msg::RunControl to_dds(const proto::RunControlMsg& m) {
  msg::RunControl o;
  o.status(m.status == proto::RunStatus::completed ? msg::RUN_COMPLETED : msg::RUN_ABORTED);
  o.reason(m.reason);
  o.final_frame(m.final_frame);
  o.final_manifest(manifest(m.final_manifest));
  msg::RunStats s;
  s.frames(m.stats.frames);
  s.final_frame(m.stats.final_frame);
  s.sim_time_s(m.stats.sim_time_s);
  s.wall_time_s(m.stats.wall_time_s);
  s.real_time_factor(m.stats.real_time_factor);
  for (const auto& ms : m.stats.members) {
    msg::MemberStats x;
    x.member_id(ms.member_id);
    x.mean_response_s(ms.mean_response_s);
    x.max_response_s(ms.max_response_s);
    x.mean_compute_s(ms.mean_compute_s);
    x.slowest_count(ms.slowest_count);
    x.lost(ms.lost);
    s.members().push_back(x);
  }
  o.stats(s);
  return o;
}
proto::RunControlMsg from_dds(const msg::RunControl& m) {
  proto::RunControlMsg o;
  o.status = m.status() == msg::RUN_COMPLETED ? proto::RunStatus::completed
                                              : proto::RunStatus::aborted;
  o.reason = m.reason();
  o.final_frame = m.final_frame();
  o.final_manifest = manifest(m.final_manifest());
  const auto& s = m.stats();
  o.stats.frames = s.frames();
  o.stats.final_frame = s.final_frame();
  o.stats.sim_time_s = s.sim_time_s();
  o.stats.wall_time_s = s.wall_time_s();
  o.stats.real_time_factor = s.real_time_factor();
  for (const auto& x : s.members()) {
    o.stats.members.push_back({x.member_id(), x.mean_response_s(), x.max_response_s(),
                               x.mean_compute_s(), x.slowest_count(), x.lost()});
  }
  return o;
}

msg::VehicleState to_dds(const proto::VehicleStateMsg& m) {
  msg::VehicleState o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.sim_time_s(m.sim_time_s);
  o.pose(pose(m.pose));
  o.linear_velocity(v3(m.linear_velocity));
  o.angular_velocity(v3(m.angular_velocity));
  o.linear_acceleration(v3(m.linear_acceleration));
  o.angular_acceleration(v3(m.angular_acceleration));
  for (const auto& w : m.wheels) {
    msg::WheelState x;
    x.pose(pose(w.pose));
    x.spin_rad_s(w.spin_rad_s);
    x.steer_angle_rad(w.steer_angle_rad);
    x.vertical_load_n(w.vertical_load_n);
    o.wheels().push_back(x);
  }
  o.steering(m.steering);
  o.throttle(m.throttle);
  o.braking(m.braking);
  o.gear(m.gear);
  o.engine_speed_rpm(m.engine_speed_rpm);
  return o;
}
proto::VehicleStateMsg from_dds(const msg::VehicleState& m) {
  proto::VehicleStateMsg o;
  o.vehicle_id = m.vehicle_id();
  o.source = m.source();
  o.frame = m.frame();
  o.sim_time_s = m.sim_time_s();
  o.pose = pose(m.pose());
  o.linear_velocity = v3(m.linear_velocity());
  o.angular_velocity = v3(m.angular_velocity());
  o.linear_acceleration = v3(m.linear_acceleration());
  o.angular_acceleration = v3(m.angular_acceleration());
  for (const auto& w : m.wheels()) {
    o.wheels.push_back({pose(w.pose()), w.spin_rad_s(), w.steer_angle_rad(), w.vertical_load_n()});
  }
  o.steering = m.steering();
  o.throttle = m.throttle();
  o.braking = m.braking();
  o.gear = m.gear();
  o.engine_speed_rpm = m.engine_speed_rpm();
  return o;
}

msg::DriverCommand to_dds(const proto::DriverCommandMsg& m) {
  msg::DriverCommand o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.steering(m.steering);
  o.throttle(m.throttle);
  o.braking(m.braking);
  return o;
}
proto::DriverCommandMsg from_dds(const msg::DriverCommand& m) {
  // Values are range-checked by the vehicle (it logs and rejects bad commands).
  return proto::DriverCommandMsg{m.vehicle_id(), m.source(),   m.frame(),
                                 m.steering(),   m.throttle(), m.braking()};
}

msg::TerrainDeformation to_dds(const proto::TerrainDeformationMsg& m) {
  msg::TerrainDeformation o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.source_index(m.source_index);
  o.spacing_m(m.spacing_m);
  o.vertices(vertices(m.vertices));
  return o;
}
proto::TerrainDeformationMsg from_dds(const msg::TerrainDeformation& m) {
  proto::TerrainDeformationMsg o;
  o.vehicle_id = m.vehicle_id();
  o.source = m.source();
  o.frame = m.frame();
  o.source_index = m.source_index();
  o.spacing_m = m.spacing_m();
  o.vertices = vertices(m.vertices(), "terrain_deformation from " + m.source());
  return o;
}

msg::TerrainSnapshot to_dds(const proto::TerrainSnapshotMsg& m) {
  msg::TerrainSnapshot o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.spacing_m(m.spacing_m);
  o.vertices(vertices(m.vertices));
  return o;
}
proto::TerrainSnapshotMsg from_dds(const msg::TerrainSnapshot& m) {
  proto::TerrainSnapshotMsg o;
  o.vehicle_id = m.vehicle_id();
  o.source = m.source();
  o.frame = m.frame();
  o.spacing_m = m.spacing_m();
  o.vertices = vertices(m.vertices(), "terrain_snapshot from " + m.source());
  return o;
}

msg::CollisionEvent to_dds(const proto::CollisionEventMsg& m) {
  msg::CollisionEvent o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.sim_time_s(m.sim_time_s);
  o.obstacle_id(m.obstacle_id);
  o.impulse_ns(m.impulse_ns);
  o.position(v3(m.position));
  return o;
}
proto::CollisionEventMsg from_dds(const msg::CollisionEvent& m) {
  return proto::CollisionEventMsg{m.vehicle_id(), m.source(),     m.frame(),
                                  m.sim_time_s(), m.obstacle_id(), m.impulse_ns(),
                                  v3(m.position())};
}

msg::GpsFix to_dds(const proto::GpsFixMsg& m) {
  msg::GpsFix o;
  header_to(o, m);
  o.latitude_deg(m.latitude_deg);
  o.longitude_deg(m.longitude_deg);
  o.altitude_m(m.altitude_m);
  o.enu_m(v3(m.enu_m));
  return o;
}
proto::GpsFixMsg from_dds(const msg::GpsFix& m) {
  proto::GpsFixMsg o;
  header_from(o, m);
  o.latitude_deg = m.latitude_deg();
  o.longitude_deg = m.longitude_deg();
  o.altitude_m = m.altitude_m();
  o.enu_m = v3(m.enu_m());
  return o;
}

msg::Imu to_dds(const proto::ImuMsg& m) {
  msg::Imu o;
  header_to(o, m);
  o.accel_mps2(v3(m.accel_mps2));
  o.gyro_rad_s(v3(m.gyro_rad_s));
  return o;
}
proto::ImuMsg from_dds(const msg::Imu& m) {
  proto::ImuMsg o;
  header_from(o, m);
  o.accel_mps2 = v3(m.accel_mps2());
  o.gyro_rad_s = v3(m.gyro_rad_s());
  return o;
}

msg::Magnetometer to_dds(const proto::MagnetometerMsg& m) {
  msg::Magnetometer o;
  header_to(o, m);
  o.heading_rad(m.heading_rad);
  o.field_ut(v3(m.field_ut));
  return o;
}
proto::MagnetometerMsg from_dds(const msg::Magnetometer& m) {
  proto::MagnetometerMsg o;
  header_from(o, m);
  o.heading_rad = m.heading_rad();
  o.field_ut = v3(m.field_ut());
  return o;
}

msg::WheelSpeeds to_dds(const proto::WheelSpeedsMsg& m) {
  msg::WheelSpeeds o;
  header_to(o, m);
  o.wheel_spin_rad_s(m.wheel_spin_rad_s);
  return o;
}
proto::WheelSpeedsMsg from_dds(const msg::WheelSpeeds& m) {
  proto::WheelSpeedsMsg o;
  header_from(o, m);
  o.wheel_spin_rad_s = m.wheel_spin_rad_s();
  return o;
}

msg::Image to_dds(const proto::ImageMsg& m) {
  msg::Image o;
  header_to(o, m);
  o.pose(pose(m.pose));
  o.width(m.width);
  o.height(m.height);
  o.encoding(m.encoding);
  o.data(m.data);
  return o;
}
proto::ImageMsg from_dds(const msg::Image& m) {
  proto::ImageMsg o;
  header_from(o, m);
  o.pose = pose(m.pose());
  o.width = m.width();
  o.height = m.height();
  o.encoding = m.encoding();
  if (o.width < 0 || o.height < 0 ||
      m.data().size() != static_cast<std::size_t>(o.width) * o.height * 3) {
    throw ProtocolError("image from " + m.source() + ": " + std::to_string(m.data().size()) +
                        " bytes for " + std::to_string(o.width) + "x" + std::to_string(o.height) +
                        " rgb8");
  }
  o.data = m.data();
  return o;
}

msg::PointCloud to_dds(const proto::PointCloudMsg& m) {
  msg::PointCloud o;
  header_to(o, m);
  o.pose(pose(m.pose));
  o.channels(m.channels);
  o.samples(m.samples);
  o.points().reserve(m.points.size());
  for (const auto& p : m.points) {
    msg::LidarPoint x;
    x.x(p.x);
    x.y(p.y);
    x.z(p.z);
    x.intensity(p.intensity);
    x.range(p.range);
    x.channel(p.channel);
    x.sample(p.sample);
    o.points().push_back(x);
  }
  return o;
}
proto::PointCloudMsg from_dds(const msg::PointCloud& m) {
  proto::PointCloudMsg o;
  header_from(o, m);
  o.pose = pose(m.pose());
  o.channels = m.channels();
  o.samples = m.samples();
  o.points.reserve(m.points().size());
  for (const auto& p : m.points()) {
    o.points.push_back({p.x(), p.y(), p.z(), p.intensity(), p.range(), p.channel(), p.sample()});
  }
  return o;
}

msg::V2VMessage to_dds(const proto::V2VMessageMsg& m) {
  msg::V2VMessage o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.number(m.sequence);
  o.sensor_time_s(m.sensor_time_s);
  o.latitude_deg(m.latitude_deg);
  o.longitude_deg(m.longitude_deg);
  o.altitude_m(m.altitude_m);
  o.speed_mps(m.speed_mps);
  o.heading_rad(m.heading_rad);
  return o;
}
// Validated: a follower steers by these numbers, so a NaN or an impossible coordinate is a
// malformed sample (ProtocolError naming the field), not something to drive towards.
proto::V2VMessageMsg from_dds(const msg::V2VMessage& m) {
  const std::string what = "v2v_message from " + m.source() + " (vehicle " + m.vehicle_id() + ")";
  auto check = [&](const char* field, double v, double lo, double hi) {
    if (!std::isfinite(v) || v < lo || v > hi) {
      throw ProtocolError(what + ": " + field + " = " + std::to_string(v) + " is not in [" +
                          std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return v;
  };
  proto::V2VMessageMsg o;
  o.vehicle_id = m.vehicle_id();
  o.source = m.source();
  o.frame = m.frame();
  o.sequence = m.number();
  o.sensor_time_s = check("sensor_time_s", m.sensor_time_s(), 0.0, 1e9);
  o.latitude_deg = check("latitude_deg", m.latitude_deg(), -90.0, 90.0);
  o.longitude_deg = check("longitude_deg", m.longitude_deg(), -180.0, 180.0);
  o.altitude_m = check("altitude_m", m.altitude_m(), -1e5, 1e5);
  o.speed_mps = check("speed_mps", m.speed_mps(), -1e3, 1e3);
  o.heading_rad = check("heading_rad", m.heading_rad(), -7.0, 7.0);
  return o;
}

msg::VehicleEvent to_dds(const proto::VehicleEventMsg& m) {
  msg::VehicleEvent o;
  o.vehicle_id(m.vehicle_id);
  o.source(m.source);
  o.frame(m.frame);
  o.sim_time_s(m.sim_time_s);
  o.kind(m.kind);
  o.detail(m.detail);
  return o;
}
proto::VehicleEventMsg from_dds(const msg::VehicleEvent& m) {
  return proto::VehicleEventMsg{m.vehicle_id(), m.source(),    m.frame(),
                                m.sim_time_s(), m.kind(),      m.detail()};
}

}  // namespace syndds::dds
