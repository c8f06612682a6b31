#include "dds/convert.hpp"

#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

#include "core/error.hpp"
#include "protocol/vertex_codec.hpp"

namespace syndds::dds {
namespace {

// ---- plain -> IDL ------------------------------------------------------------------------------
// put(idl, plain) fills an IDL value from a plain one: structs field by field through their field
// lists, sequences element by element, and the types below that the two sides spell differently.

void put(msg::Vec3& o, const Vec3& v) {
  o.x(v.x());
  o.y(v.y());
  o.z(v.z());
}
void put(msg::Quat& o, const Quat& q) {
  o.w(q.w());
  o.x(q.x());
  o.y(q.y());
  o.z(q.z());
}
void put(msg::Pose& o, const Pose& p) {
  put(o.position(), p.position);
  put(o.orientation(), p.orientation);
}
void put(msg::MemberKind& o, proto::MemberKind kind) { o = static_cast<msg::MemberKind>(kind); }
void put(msg::RunStatus& o, proto::RunStatus status) {
  o = status == proto::RunStatus::completed ? msg::RUN_COMPLETED : msg::RUN_ABORTED;
}
void put(std::string& o, proto::Topic topic) { o = std::string(proto::to_string(topic)); }
void put(std::vector<std::uint8_t>& o, const std::vector<proto::TerrainVertexMsg>& v) {
  o = proto::pack_vertices(v);
}
template <typename I, typename P>
void put(std::vector<I>& o, const std::vector<P>& v);
template <typename I, typename P>
void put(I& o, const P& v);

template <typename I, typename P>
void put(std::vector<I>& o, const std::vector<P>& v) {
  if constexpr (std::is_same_v<I, P>) {
    o = v;
  } else {
    o.resize(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) put(o[k], v[k]);
  }
}

template <typename I, typename P>
void put(I& o, const P& v) {
  if constexpr (proto::HasFields<P>) {
    proto::for_each_field<P>([&](const char*, auto member, auto idl) { put(idl(o), v.*member); });
  } else {
    // Scalars and strings: the plain field has exactly the type of its IDL member.
    static_assert(std::is_same_v<I, P>, "a plain field and its IDL member differ in type");
    o = v;
  }
}

// ---- IDL -> plain ------------------------------------------------------------------------------
// get(plain, idl) is the inverse of put; what cannot be represented (an unknown topic name)
// raises ProtocolError here, everything else is checked per message below.

void get(Vec3& o, const msg::Vec3& v) { o = Vec3(v.x(), v.y(), v.z()); }
void get(Quat& o, const msg::Quat& q) { o = Quat(q.w(), q.x(), q.y(), q.z()); }
void get(Pose& o, const msg::Pose& p) {
  get(o.position, p.position());
  get(o.orientation, p.orientation());
}
// In range: check_idl(MemberAnnounce) ran before.
void get(proto::MemberKind& o, msg::MemberKind kind) { o = static_cast<proto::MemberKind>(kind); }
void get(proto::RunStatus& o, msg::RunStatus status) {
  o = status == msg::RUN_COMPLETED ? proto::RunStatus::completed : proto::RunStatus::aborted;
}
void get(proto::Topic& o, const std::string& name) {
  if (!proto::topic_from_string(name, o)) throw ProtocolError("unknown topic '" + name + "'");
}
void get(proto::TopicCount& o, const msg::TopicCount& c);
void get(std::vector<proto::TerrainVertexMsg>& o, const std::vector<std::uint8_t>& bytes) {
  o = proto::unpack_vertices(bytes);
}
void get(proto::TerrainDeformationMsg& o, const msg::TerrainDeformation& m);
void get(proto::TerrainSnapshotMsg& o, const msg::TerrainSnapshot& m);
void get(proto::TerrainPatchMsg& o, const msg::TerrainPatch& m);
template <typename P, typename I>
void get(std::vector<P>& o, const std::vector<I>& v);
template <typename P, typename I>
void get(P& o, const I& v);
template <typename P, typename I>
void get_fields(P& o, const I& v);

template <typename P, typename I>
void get(std::vector<P>& o, const std::vector<I>& v) {
  if constexpr (std::is_same_v<I, P>) {
    o = v;
  } else {
    o.resize(v.size());
    for (std::size_t k = 0; k < v.size(); ++k) get(o[k], v[k]);
  }
}

template <typename P, typename I>
void get_fields(P& o, const I& v) {
  proto::for_each_field<P>([&](const char*, auto member, auto idl) { get(o.*member, idl(v)); });
}

template <typename P, typename I>
void get(P& o, const I& v) {
  if constexpr (proto::HasFields<P>) {
    get_fields(o, v);
  } else {
    static_assert(std::is_same_v<I, P>, "a plain field and its IDL member differ in type");
    o = v;
  }
}

// A list that does not unpack is named with its topic and writer, as a non-finite value is.
template <typename P, typename I>
void get_vertex_message(P& o, const I& m) {
  try {
    get_fields(o, m);
  } catch (const ProtocolError& e) {
    throw ProtocolError(std::string(proto::TopicTraits<proto::TopicOf<P>::value>::name) +
                        " from " + m.source() + ": " + e.what());
  }
}
void get(proto::TerrainDeformationMsg& o, const msg::TerrainDeformation& m) {
  get_vertex_message(o, m);
}
void get(proto::TerrainSnapshotMsg& o, const msg::TerrainSnapshot& m) {
  get_vertex_message(o, m);
}
void get(proto::TerrainPatchMsg& o, const msg::TerrainPatch& m) { get_vertex_message(o, m); }

void get(proto::TopicCount& o, const msg::TopicCount& c) {
  if (!proto::topic_from_string(c.topic(), o.topic)) {
    throw ProtocolError("manifest entry names unknown topic '" + c.topic() + "' (writer " +
                        c.writer() + ")");
  }
  get_fields(o, c);
}

// ---- checks of incoming samples ------------------------------------------------------------
// check_idl runs on the sample as received, check on the converted one; both raise ProtocolError
// naming the field. Driver commands are range-checked by the vehicle (it logs and rejects bad
// commands), so they pass here.

template <typename I>
void check_idl(const I&) {}
void check_idl(const msg::MemberAnnounce& m) {
  const auto kind = static_cast<int>(m.kind());
  if (kind < 0 || kind > static_cast<int>(proto::MemberKind::coordinator)) {
    throw ProtocolError("member_announce from '" + m.member_id() + "': kind " +
                        std::to_string(kind) + " is out of range");
  }
}

template <typename P>
void check(const P&) {}

// Every floating-point field of every vertex finite, or the vertex and the field are named.
template <typename P>
void check_vertices(const P& m) {
  const std::string what = std::string(proto::TopicTraits<proto::TopicOf<P>::value>::name) +
                           " from " + m.source;
  for (const auto& v : m.vertices) {
    proto::for_each_field<proto::TerrainVertexMsg>([&](const char* name, auto member, auto) {
      if constexpr (std::is_floating_point_v<std::remove_cvref_t<decltype(v.*member)>>) {
        if (!std::isfinite(v.*member)) {
          throw ProtocolError(what + ": vertex (" + std::to_string(v.i) + ", " +
                              std::to_string(v.j) + ") " + name + " is not finite");
        }
      }
    });
  }
}
void check(const proto::TerrainDeformationMsg& m) { check_vertices(m); }
void check(const proto::TerrainSnapshotMsg& m) { check_vertices(m); }
void check(const proto::TerrainPatchMsg& m) { check_vertices(m); }

void check(const proto::ImageMsg& m) {
  if (m.width < 0 || m.height < 0 ||
      m.data.size() != static_cast<std::size_t>(m.width) * m.height * 3) {
    throw ProtocolError("image from " + m.source + ": " + std::to_string(m.data.size()) +
                        " bytes for " + std::to_string(m.width) + "x" + std::to_string(m.height) +
                        " rgb8");
  }
}

// A follower steers by these numbers, so a NaN or an impossible coordinate is a malformed
// sample, not something to drive towards.
void check(const proto::V2VMessageMsg& m) {
  const std::string what = "v2v_message from " + m.source + " (vehicle " + m.vehicle_id + ")";
  auto in = [&](const char* field, double v, double lo, double hi) {
    if (!std::isfinite(v) || v < lo || v > hi) {
      throw ProtocolError(what + ": " + field + " = " + std::to_string(v) + " is not in [" +
                          std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
  };
  in("sensor_time_s", m.sensor_time_s, 0.0, 1e9);
  in("latitude_deg", m.latitude_deg, -90.0, 90.0);
  in("longitude_deg", m.longitude_deg, -180.0, 180.0);
  in("altitude_m", m.altitude_m, -1e5, 1e5);
  in("speed_mps", m.speed_mps, -1e3, 1e3);
  in("heading_rad", m.heading_rad, -7.0, 7.0);
}

// A radar's detections are drawn and may be acted on: every number finite, or the detection
// and the field are named.
void check(const proto::RadarScanMsg& m) {
  const std::string what = "radar from " + m.source + " (sensor " + m.stamp.sensor_id + ")";
  if (!m.pose.position.allFinite() || !m.pose.orientation.coeffs().allFinite() ||
      !m.velocity.allFinite()) {
    throw ProtocolError(what + ": pose or velocity is not finite");
  }
  for (std::size_t k = 0; k < m.detections.size(); ++k) {
    proto::for_each_field<proto::RadarDetectionMsg>([&](const char* name, auto member, auto) {
      if constexpr (std::is_floating_point_v<std::remove_cvref_t<decltype(m.detections[k].*member)>>) {
        if (!std::isfinite(m.detections[k].*member)) {
          throw ProtocolError(what + ": detection " + std::to_string(k) + " " + name +
                              " is not finite");
        }
      }
    });
  }
}

// Another vehicle's process feels these bodies: a NaN or a negative footprint is malformed.
void check_body(const proto::VehicleBodyMsg& b, const std::string& what) {
  auto finite = [&](const char* field, const auto& v) {
    bool ok = true;
    if constexpr (std::is_same_v<std::remove_cvref_t<decltype(v)>, Pose>) {
      ok = v.position.allFinite() && v.orientation.coeffs().allFinite() &&
           v.orientation.norm() > 0.0;
    } else if constexpr (std::is_floating_point_v<std::remove_cvref_t<decltype(v)>>) {
      ok = std::isfinite(v) && v >= 0.0;
    } else {
      ok = v.allFinite();
    }
    if (!ok) {
      throw ProtocolError(what + ": body of vehicle '" + b.vehicle_id + "': " + field +
                          " is not finite (or a zero quaternion, or negative)");
    }
  };
  finite("pose", b.pose);
  finite("linear_velocity", b.linear_velocity);
  finite("angular_velocity", b.angular_velocity);
  for (const auto& w : b.wheels) finite("wheels", w);
  if (!std::isfinite(b.footprint_offset_m)) finite("footprint_offset_m", -1.0);
  finite("footprint_half_length_m", b.footprint_half_length_m);
  finite("footprint_half_width_m", b.footprint_half_width_m);
}
void check(const proto::FrameDoneMsg& m) {
  for (const auto& b : m.body) check_body(b, "frame_done from " + m.member_id);
}
void check(const proto::FrameDonesMsg& m) {
  for (const auto& d : m.dones) check(d);
}
void check(const proto::FrameGrantMsg& m) {
  for (const auto& b : m.bodies) check_body(b, "frame_grant " + std::to_string(m.frame));
}

}  // namespace

#define SYNDDS_DDS_CONVERT_(MSG, IDL)         \
  msg::IDL to_dds(const proto::MSG& m) {      \
    msg::IDL o;                               \
    put(o, m);                                \
    return o;                                 \
  }                                           \
  proto::MSG from_dds(const msg::IDL& m) {    \
    check_idl(m);                             \
    proto::MSG o;                             \
    get(o, m);                                \
    check(o);                                 \
    return o;                                 \
  }
#define SYNDDS_DDS_CONVERT_TOPIC_(TOPIC, MSG, IDL, LIST, PER_FRAME) SYNDDS_DDS_CONVERT_(MSG, IDL)
SYNDDS_PROTOCOL_MESSAGES(SYNDDS_DDS_CONVERT_)
SYNDDS_DATA_TOPICS(SYNDDS_DDS_CONVERT_TOPIC_)
#undef SYNDDS_DDS_CONVERT_TOPIC_
#undef SYNDDS_DDS_CONVERT_

}  // namespace syndds::dds
