// The conversions between the plain messages and the IDL types, for every message there is:
// each field filled with a value of its own survives plain -> IDL -> plain, every member of a
// struct is in its field list and every IDL member has a field, and malformed samples are
// refused naming the field. The messages are taken from the topic tables and the fields from the
// field lists, so a new topic or field is covered without touching this file.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "core/error.hpp"
#include "dds/convert.hpp"

using namespace syndds;
namespace sdds = syndds::dds;

namespace {

// ---- a distinct, non-default value for every field ------------------------------------------
// Numbers count up from 100 (clear of every default), small enough for the range checks of
// incoming samples (v2v headings, latitudes).

template <typename T>
void fill(T& v, int& n);

template <typename T>
void fill(std::vector<T>& v, int& n) {
  v.resize(2);
  for (auto& e : v) fill(e, n);
}

template <typename T>
void fill(T& v, int& n) {
  ++n;
  if constexpr (proto::HasFields<T>) {
    proto::for_each_field<T>([&](const char*, auto member, auto) { fill(v.*member, n); });
  } else if constexpr (std::is_same_v<T, std::string>) {
    v = "text" + std::to_string(n);
  } else if constexpr (std::is_same_v<T, bool>) {
    v = true;
  } else if constexpr (std::is_floating_point_v<T>) {
    v = static_cast<T>(0.25 + 0.01 * n);
  } else if constexpr (std::is_integral_v<T>) {
    v = static_cast<T>(n);
  } else if constexpr (std::is_same_v<T, proto::MemberKind>) {
    v = static_cast<proto::MemberKind>(1 + n % 5);  // vehicle (the default) is 0, coordinator 5
  } else if constexpr (std::is_same_v<T, proto::RunStatus>) {
    v = proto::RunStatus::aborted;
  } else if constexpr (std::is_same_v<T, proto::Topic>) {
    v = proto::kAllDataTopics[1 + n % (std::size(proto::kAllDataTopics) - 1)];
  } else if constexpr (std::is_same_v<T, Vec3>) {
    v = Vec3(0.01 * n, 0.02 * n, -0.03 * n);
  } else if constexpr (std::is_same_v<T, Quat>) {
    v = Quat(0.1 * n, 0.2 * n, 0.3 * n, 0.4 * n);  // raw coefficients travel as they are
  } else if constexpr (std::is_same_v<T, Pose>) {
    fill(v.position, n);
    fill(v.orientation, n);
  } else {
    static_assert(sizeof(T) == 0, "fill: a field type this test does not know");
  }
}

// A filled message that its receiver accepts: an image's bytes match its size.
template <typename T>
T filled() {
  T v;
  int n = 100;
  fill(v, n);
  if constexpr (std::is_same_v<T, proto::ImageMsg>) {
    v.width = 3;
    v.height = 2;
    v.data.assign(18, 0);
    for (std::size_t k = 0; k < v.data.size(); ++k) v.data[k] = static_cast<std::uint8_t>(7 * k);
  }
  return v;
}

// ---- field-by-field comparison ---------------------------------------------------------------
// Collects the paths of the leaves that are equal and of those that differ.
struct Comparison {
  std::vector<std::string> equal;
  std::vector<std::string> different;
};

template <typename T>
void compare(const T& a, const T& b, const std::string& path, Comparison& out) {
  if constexpr (proto::HasFields<T>) {
    proto::for_each_field<T>([&](const char* name, auto member, auto) {
      compare(a.*member, b.*member, path + "." + name, out);
    });
  } else if constexpr (requires { a.size(); a[0]; } && !std::is_same_v<T, std::string> &&
                       !std::is_same_v<T, Vec3>) {
    if (a.size() != b.size()) {
      out.different.push_back(path + " (size)");
      return;
    }
    for (std::size_t k = 0; k < a.size(); ++k) {
      compare(a[k], b[k], path + "[" + std::to_string(k) + "]", out);
    }
  } else if constexpr (std::is_same_v<T, Pose>) {
    compare(a.position, b.position, path + ".position", out);
    compare(a.orientation, b.orientation, path + ".orientation", out);
  } else if constexpr (std::is_same_v<T, Quat>) {
    (a.coeffs() == b.coeffs() ? out.equal : out.different).push_back(path);
  } else {
    (a == b ? out.equal : out.different).push_back(path);
  }
}

// ---- how many members a struct really has --------------------------------------------------
// The largest N for which T{x1, ..., xN} compiles, x converting to anything: the member count of
// an aggregate (no member here is an aggregate that would take several of them).
struct AnyField {
  template <typename T>
  operator T() const;
};
template <typename T, typename... A>
constexpr std::size_t member_count() {
  if constexpr (requires { T{A{}..., AnyField{}}; }) {
    return member_count<T, A..., AnyField>();
  } else {
    return sizeof...(A);
  }
}

// Members of struct `name` in idl/syndds.idl (one declaration per member, comments ignored).
std::size_t idl_member_count(const std::string& name) {
  std::ifstream in(SYNDDS_TEST_IDL);
  std::stringstream s;
  s << in.rdbuf();
  const std::string text = std::regex_replace(s.str(), std::regex("//[^\n]*"), "");
  std::smatch m;
  if (!std::regex_search(text, m, std::regex("struct\\s+" + name + "\\s*\\{([^}]*)\\}"))) {
    ADD_FAILURE() << "struct " << name << " not found in " << SYNDDS_TEST_IDL;
    return 0;
  }
  const std::string body = m[1].str();
  return static_cast<std::size_t>(std::count(body.begin(), body.end(), ';'));
}

template <typename Plain>
void expect_complete_field_list(const std::string& idl_name) {
  SCOPED_TRACE(idl_name);
  EXPECT_EQ(proto::Fields<Plain>::count, member_count<Plain>())
      << "the field list of the plain struct misses members";
  EXPECT_EQ(proto::Fields<Plain>::count, idl_member_count(idl_name))
      << "the plain struct and the IDL type differ in their number of members";
}

template <typename Plain, typename Idl>
void expect_round_trip(const std::string& idl_name) {
  SCOPED_TRACE(idl_name);
  expect_complete_field_list<Plain>(idl_name);
  const Plain sent = filled<Plain>();
  Comparison vs_default;
  compare(sent, Plain{}, "", vs_default);
  EXPECT_TRUE(vs_default.equal.empty())
      << "fields left at their default: " << ::testing::PrintToString(vs_default.equal);
  const Idl wire = sdds::to_dds(sent);
  const Plain back = sdds::from_dds(wire);
  Comparison round;
  compare(sent, back, "", round);
  EXPECT_TRUE(round.different.empty())
      << "fields changed on the way: " << ::testing::PrintToString(round.different);
  EXPECT_FALSE(round.equal.empty());
}

template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const ProtocolError& e) {
    return e.what();
  }
  return "(accepted)";
}

}  // namespace

TEST(Convert, EveryDataTopicRoundTripsEveryField) {
#define SYNDDS_TEST_TOPIC_(TOPIC, MSG, IDL, LIST, PER_FRAME) \
  expect_round_trip<proto::MSG, msg::IDL>(#IDL);
  SYNDDS_DATA_TOPICS(SYNDDS_TEST_TOPIC_)
#undef SYNDDS_TEST_TOPIC_
}

TEST(Convert, EveryProtocolMessageRoundTripsEveryField) {
#define SYNDDS_TEST_MESSAGE_(MSG, IDL) expect_round_trip<proto::MSG, msg::IDL>(#IDL);
  SYNDDS_PROTOCOL_MESSAGES(SYNDDS_TEST_MESSAGE_)
#undef SYNDDS_TEST_MESSAGE_
}

TEST(Convert, NestedStructsListEveryMember) {
  expect_complete_field_list<proto::WheelStateMsg>("WheelState");
  // Terrain vertices travel packed (protocol/vertex_codec.hpp): no IDL struct to compare with;
  // the round trips above fill every field of every vertex.
  EXPECT_EQ(proto::Fields<proto::TerrainVertexMsg>::count,
            member_count<proto::TerrainVertexMsg>());
  expect_complete_field_list<proto::SensorStampMsg>("SensorStamp");
  expect_complete_field_list<proto::PointMsg>("LidarPoint");
  expect_complete_field_list<proto::TopicCount>("TopicCount");
  expect_complete_field_list<proto::MemberStatsMsg>("MemberStats");
  expect_complete_field_list<proto::RunStatsMsg>("RunStats");
}

TEST(Convert, FrameGrantCarriesDepartedMembers) {
  proto::FrameGrantMsg g;
  g.frame = 9;
  g.departed = {"vehicle/b", "sensor/b"};
  const msg::FrameGrant wire = sdds::to_dds(g);
  EXPECT_EQ(wire.departed(), g.departed);
  EXPECT_EQ(sdds::from_dds(wire).departed, g.departed);
}

TEST(Convert, RenamedFieldsUseTheirIdlMember) {
  proto::SensorStampMsg s;
  s.sequence = 17;
  proto::GpsFixMsg g;
  g.stamp = s;
  EXPECT_EQ(sdds::to_dds(g).stamp().number(), 17u);
  proto::V2VMessageMsg v;
  v.sequence = 23;
  EXPECT_EQ(sdds::to_dds(v).number(), 23u);
}

TEST(Convert, UnknownManifestTopicIsRefusedWithItsWriter) {
  msg::TopicCount c;
  c.topic("vehicle_speed");
  c.writer("vehicle/x");
  const std::string expected = "unknown topic 'vehicle_speed' (writer vehicle/x)";
  msg::FrameGrant g;
  g.manifest().push_back(c);
  EXPECT_NE(error_of([&] { sdds::from_dds(g); }).find(expected), std::string::npos);
  msg::FrameDone d;
  d.published().push_back(c);
  EXPECT_NE(error_of([&] { sdds::from_dds(d); }).find(expected), std::string::npos);
  msg::RunControl r;
  r.final_manifest().push_back(c);
  EXPECT_NE(error_of([&] { sdds::from_dds(r); }).find(expected), std::string::npos);
}

TEST(Convert, MemberKindOutOfRangeIsRefused) {
  msg::MemberAnnounce a;
  a.member_id("vehicle/z");
  a.kind(static_cast<msg::MemberKind>(6));
  EXPECT_EQ(error_of([&] { sdds::from_dds(a); }),
            "member_announce from 'vehicle/z': kind 6 is out of range");
  a.kind(msg::MEMBER_COORDINATOR);
  EXPECT_EQ(sdds::from_dds(a).kind, proto::MemberKind::coordinator);
}

TEST(Convert, NonFiniteTerrainVertexNamesTheVertexAndTheField) {
  std::vector<std::string> fields;
  proto::for_each_field<proto::TerrainVertexMsg>([&](const char* name, auto member, auto) {
    if constexpr (std::is_floating_point_v<
                      std::remove_cvref_t<decltype(proto::TerrainVertexMsg{}.*member)>>) {
      fields.push_back(name);
    }
  });
  ASSERT_EQ(fields.size(), 4u);  // height, level_initial, sinkage_plastic, sigma_yield
  for (const auto& field : fields) {
    for (double x : {std::nan(""), HUGE_VAL}) {
      // A sender that does not check: the packed list carries the value exactly.
      proto::TerrainDeformationMsg d;
      d.source = "vehicle/y";
      d.vertices.resize(2);
      auto& v = d.vertices[1];
      v.i = 3;
      v.j = 4;
      if (field == "height") v.height = x;
      if (field == "level_initial") v.level_initial = x;
      if (field == "sinkage_plastic") v.sinkage_plastic = x;
      if (field == "sigma_yield") v.sigma_yield = x;
      EXPECT_EQ(error_of([&] { sdds::from_dds(sdds::to_dds(d)); }),
                "terrain_deformation from vehicle/y: vertex (3, 4) " + field + " is not finite");
      proto::TerrainSnapshotMsg s;
      s.source = "vehicle/y";
      s.vertices = d.vertices;
      EXPECT_EQ(error_of([&] { sdds::from_dds(sdds::to_dds(s)); }),
                "terrain_snapshot from vehicle/y: vertex (3, 4) " + field + " is not finite");
    }
  }
}

TEST(Convert, NonFiniteRadarDetectionNamesTheDetectionAndTheField) {
  proto::RadarScanMsg r;
  r.source = "sensor/y";
  r.stamp.sensor_id = "front_radar";
  r.detections.resize(3);
  r.detections[2].radial_speed_mps = std::nanf("");
  EXPECT_EQ(error_of([&] { sdds::from_dds(sdds::to_dds(r)); }),
            "radar from sensor/y (sensor front_radar): detection 2 radial_speed_mps is not finite");
  r.detections[2].radial_speed_mps = 1.0f;
  r.velocity.x() = HUGE_VAL;
  EXPECT_EQ(error_of([&] { sdds::from_dds(sdds::to_dds(r)); }),
            "radar from sensor/y (sensor front_radar): pose or velocity is not finite");
  r.velocity.x() = 0.0;
  EXPECT_EQ(sdds::from_dds(sdds::to_dds(r)).detections.size(), 3u);
}

// A packed list that does not decode exactly is refused naming the topic, the writer and the
// byte (a truncated sample, a corrupted length, garbage after the list).
TEST(Convert, MalformedPackedVerticesAreRefusedNamingTheByte) {
  proto::TerrainDeformationMsg d;
  d.source = "vehicle/y";
  d.vertices = {{3, 4, -0.01, 0.0, 0.01, 1e4}, {3, 5, -0.02, 0.0, 0.02, 2e4}};
  const msg::TerrainDeformation good = sdds::to_dds(d);
  const std::string prefix = "terrain_deformation from vehicle/y: packed vertices: ";
  msg::TerrainDeformation t = good;
  t.vertices().pop_back();
  EXPECT_EQ(error_of([&] { sdds::from_dds(t); }).rfind(prefix + "truncated list at byte", 0), 0u)
      << error_of([&] { sdds::from_dds(t); });
  t = good;
  t.vertices().push_back(0);
  EXPECT_EQ(error_of([&] { sdds::from_dds(t); }),
            prefix + "1 bytes after the last vertex at byte " +
                std::to_string(good.vertices().size()) + " of " +
                std::to_string(good.vertices().size() + 1));
  t = good;
  t.vertices()[3] = 0x9f;  // first vertex: after i and j (one byte each), a length of 15
  EXPECT_EQ(error_of([&] { sdds::from_dds(t); }), prefix + "field length 15 over 8 at byte 5 of " +
                                                       std::to_string(good.vertices().size()));
  t = good;
  t.vertices()[0] = 100;  // 100 vertices announced in a few bytes
  EXPECT_NE(error_of([&] { sdds::from_dds(t); }).find("100 vertices announced"), std::string::npos);
}

TEST(Convert, ImageWhoseBytesDoNotMatchItsSizeIsRefused) {
  proto::ImageMsg m;
  m.source = "sensor/cam";
  m.width = 2;
  m.height = 1;
  m.data.assign(5, 0);
  EXPECT_EQ(error_of([&] { sdds::from_dds(sdds::to_dds(m)); }),
            "image from sensor/cam: 5 bytes for 2x1 rgb8");
  m.width = -2;
  m.height = -3;
  m.data.assign(18, 0);
  EXPECT_EQ(error_of([&] { sdds::from_dds(sdds::to_dds(m)); }),
            "image from sensor/cam: 18 bytes for -2x-3 rgb8");
  m.width = 3;
  m.height = 2;
  EXPECT_EQ(sdds::from_dds(sdds::to_dds(m)).data.size(), 18u);
}

TEST(Convert, ImpossibleV2VValuesAreRefusedNamingTheField) {
  const struct {
    const char* field;
    double proto::V2VMessageMsg::*member;
    double bad;
  } cases[] = {
      {"sensor_time_s", &proto::V2VMessageMsg::sensor_time_s, -1.0},
      {"latitude_deg", &proto::V2VMessageMsg::latitude_deg, 90.5},
      {"longitude_deg", &proto::V2VMessageMsg::longitude_deg, -181.0},
      {"altitude_m", &proto::V2VMessageMsg::altitude_m, 2e5},
      {"speed_mps", &proto::V2VMessageMsg::speed_mps, std::nan("")},
      {"heading_rad", &proto::V2VMessageMsg::heading_rad, INFINITY},
  };
  for (const auto& c : cases) {
    proto::V2VMessageMsg m;
    m.vehicle_id = "lead";
    m.source = "vehicle/lead";
    m.*c.member = c.bad;
    const std::string error = error_of([&] { sdds::from_dds(sdds::to_dds(m)); });
    EXPECT_EQ(error.rfind(std::string("v2v_message from vehicle/lead (vehicle lead): ") +
                              c.field + " = ", 0),
              0u)
        << error;
  }
}

TEST(Convert, VehicleStateRoundTripsExactly) {
  proto::VehicleStateMsg s;
  s.vehicle_id = "v1";
  s.source = "vehicle/v1";
  s.frame = 42;
  s.sim_time_s = 0.42;
  s.pose.position = Vec3(1.0 / 3.0, -2.5, 0.467);
  s.pose.orientation = Quat(Eigen::AngleAxisd(0.3, Vec3(0.1, 0.2, 1.0).normalized()));
  s.linear_velocity = Vec3(1, 2, 3);
  s.angular_acceleration = Vec3(-1e-300, 4, 5);
  s.wheels.push_back({s.pose, 12.5, 0.1, 6000.0});
  s.steering = -0.25;
  s.throttle = 0.75;
  s.gear = 2;
  s.engine_speed_rpm = 1650.5;
  const auto back = sdds::from_dds(sdds::to_dds(s));
  EXPECT_EQ(back.vehicle_id, s.vehicle_id);
  EXPECT_EQ(back.frame, s.frame);
  EXPECT_EQ(back.pose.position, s.pose.position);
  EXPECT_EQ(back.pose.orientation.coeffs(), s.pose.orientation.coeffs());
  EXPECT_EQ(back.angular_acceleration, s.angular_acceleration);
  ASSERT_EQ(back.wheels.size(), 1u);
  EXPECT_EQ(back.wheels[0].spin_rad_s, 12.5);
  EXPECT_EQ(back.engine_speed_rpm, s.engine_speed_rpm);
  EXPECT_EQ(back.gear, 2);
}

TEST(Convert, ControlMessagesRoundTrip) {
  proto::RunControlMsg c;
  c.status = proto::RunStatus::aborted;
  c.reason = "member vehicle/a lost";
  c.final_frame = 7;
  c.final_manifest = {{proto::Topic::collision_event, "a", "vehicle/a", 2}};
  c.stats.frames = 8;
  c.stats.members = {{"vehicle/a", 0.001, 0.002, 0.0005, 3, true}};
  const auto back = sdds::from_dds(sdds::to_dds(c));
  EXPECT_EQ(back.status, proto::RunStatus::aborted);
  EXPECT_EQ(back.reason, c.reason);
  EXPECT_EQ(back.final_manifest, c.final_manifest);
  ASSERT_EQ(back.stats.members.size(), 1u);
  EXPECT_TRUE(back.stats.members[0].lost);
  EXPECT_EQ(back.stats.members[0].slowest_count, 3u);
}

TEST(Convert, MalformedSamplesAreRejectedWithTheField) {
  msg::FrameGrant g;
  msg::TopicCount c;
  c.topic("vehicle_speed");
  c.writer("vehicle/x");
  g.manifest().push_back(c);
  try {
    sdds::from_dds(g);
    FAIL() << "accepted an unknown topic";
  } catch (const ProtocolError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown topic 'vehicle_speed' (writer vehicle/x)"),
              std::string::npos)
        << e.what();
  }
  proto::TerrainDeformationMsg t;
  t.source = "vehicle/y";
  t.vertices.push_back({3, 4, std::nan(""), 0.0, 0.0, 0.0});
  EXPECT_THROW(sdds::from_dds(sdds::to_dds(t)), ProtocolError);
}
