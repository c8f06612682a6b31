#pragma once
// Plain C++ mirrors of the IDL types in idl/syndds.idl. common/ code speaks these; the DDS
// layer (services/dds) converts them to and from the generated types at the edge.
//
// Frame convention (see docs/time-protocol.md): frame k ends at sim time t_k = k * heartbeat_s.
// Frame 0 is the initial frame (vehicles publish their initial state, nothing steps); in frame
// k >= 1 vehicles advance from t_{k-1} to t_k. A sample "stamped k" was produced in frame k.
#include <cstdint>
#include <string>
#include <iterator>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/math.hpp"

namespace syndds::proto {

inline constexpr std::int32_t kProtocolVersion = 1;

enum class MemberKind : std::uint8_t { vehicle, controller, recorder, sensor, external, coordinator };
std::string_view to_string(MemberKind kind);

/// Data topics that take part in the frame manifest. Adding one: a message struct below, a
/// TopicTraits specialisation, a list in FrameSamples (agent.hpp), an IDL type and its
/// conversions (services/dds/convert.*) and DdsType (services/dds/topics.hpp).
enum class Topic : std::uint8_t {
  vehicle_state,
  driver_command,
  terrain_deformation,
  terrain_snapshot,
  collision_event,
  gps_fix,
  imu,
  magnetometer,
  wheel_speeds,
  image,
  point_cloud,
  v2v_message,
  vehicle_event,
};
inline constexpr Topic kAllDataTopics[] = {
    Topic::vehicle_state, Topic::driver_command, Topic::terrain_deformation,
    Topic::terrain_snapshot, Topic::collision_event, Topic::gps_fix, Topic::imu, Topic::magnetometer,
    Topic::wheel_speeds, Topic::image, Topic::point_cloud, Topic::v2v_message,
    Topic::vehicle_event};
/// Stable short name used in manifests, logs and DDS topic names ("vehicle_state").
std::string_view to_string(Topic topic);
/// Inverse of to_string; returns false for unknown names.
bool topic_from_string(std::string_view name, Topic& topic);

struct WheelStateMsg {
  Pose pose;                      // wheel centre and orientation in the world frame
  double spin_rad_s = 0.0;        // rotation rate about the wheel axle
  double steer_angle_rad = 0.0;   // steering angle of this wheel
  double vertical_load_n = 0.0;   // normal force from the ground (0 when airborne)
};

struct VehicleStateMsg {
  std::string vehicle_id;
  std::string source;             // member id of the writer
  std::int64_t frame = 0;
  double sim_time_s = 0.0;
  Pose pose;                      // chassis reference frame in the world
  Vec3 linear_velocity = Vec3::Zero();        // world frame, m/s
  Vec3 angular_velocity = Vec3::Zero();       // world frame, rad/s
  Vec3 linear_acceleration = Vec3::Zero();    // world frame, m/s^2 (no gravity)
  Vec3 angular_acceleration = Vec3::Zero();   // world frame, rad/s^2
  std::vector<WheelStateMsg> wheels;
  double steering = 0.0;          // applied driver inputs
  double throttle = 0.0;
  double braking = 0.0;
  std::int32_t gear = 0;
  double engine_speed_rpm = 0.0;
};

struct DriverCommandMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double steering = 0.0;  // [-1, 1], positive turns left
  double throttle = 0.0;  // [0, 1]
  double braking = 0.0;   // [0, 1]
};

struct TerrainVertexMsg {
  std::int32_t i = 0;
  std::int32_t j = 0;
  double height = 0.0;           // current surface level
  double level_initial = 0.0;    // undeformed level incl. bulldozed material
  double sinkage_plastic = 0.0;  // permanent sinkage below level_initial
  double sigma_yield = 0.0;      // highest Bekker stress reached
};

struct TerrainDeformationMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  std::uint32_t source_index = 0;  // the writer's rank in the member list (merge tie-break)
  double spacing_m = 0.0;
  std::vector<TerrainVertexMsg> vertices;
};

/// Every stored vertex of one vehicle's terrain copy at the end of `frame` (late joiners).
struct TerrainSnapshotMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double spacing_m = 0.0;
  std::vector<TerrainVertexMsg> vertices;
};

struct CollisionEventMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double sim_time_s = 0.0;
  std::string obstacle_id;
  double impulse_ns = 0.0;
  Vec3 position = Vec3::Zero();
};

/// Stamp of a synthetic sensor sample: which sensor, its sample number, when it was measured
/// and when it became available (measurement time + modelled lag).
struct SensorStampMsg {
  std::string sensor_id;
  std::uint64_t sequence = 0;
  double time_s = 0.0;
  double available_s = 0.0;
};

struct GpsFixMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;
  double altitude_m = 0.0;
  Vec3 enu_m = Vec3::Zero();  // the same fix in the scenario's local frame
};

struct ImuMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  Vec3 accel_mps2 = Vec3::Zero();  // specific force in the sensor frame (at rest: +g up)
  Vec3 gyro_rad_s = Vec3::Zero();
};

struct MagnetometerMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  double heading_rad = 0.0;  // compass heading, clockwise from true north, [0, 2 pi)
  Vec3 field_ut = Vec3::Zero();
};

struct WheelSpeedsMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  std::vector<double> wheel_spin_rad_s;  // FL, FR, RL, RR
};

struct ImageMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  Pose pose;                   // camera pose in the world (x forward, y left, z up)
  std::int32_t width = 0;
  std::int32_t height = 0;
  std::string encoding = "rgb8";
  std::vector<std::uint8_t> data;  // row-major, top row first
};

struct PointMsg {
  float x = 0, y = 0, z = 0;  // sensor frame, metres
  float intensity = 0;
  float range = 0;
  std::uint16_t channel = 0;
  std::uint16_t sample = 0;
};

struct PointCloudMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  Pose pose;  // lidar pose in the world
  std::int32_t channels = 0;
  std::int32_t samples = 0;
  std::vector<PointMsg> points;
};

/// Vehicle-to-vehicle broadcast: what a vehicle tells the others about itself, from its own
/// sensors (GPS, compass, tachometer: noise and lag included, never ground truth).
struct V2VMessageMsg {
  std::string vehicle_id;         // the sender
  std::string source;
  std::int64_t frame = 0;         // frame it was published in
  std::uint64_t sequence = 0;     // the sender's message number (0, 1, ...; dropped ones too)
  double sensor_time_s = 0.0;     // when its position (GPS fix) was measured
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;
  double altitude_m = 0.0;
  double speed_mps = 0.0;         // from the wheel tachometer
  double heading_rad = 0.0;       // compass: clockwise from true north, [0, 2 pi)
};

/// Something that happened to a vehicle and is worth a row in events.csv: a follower that lost
/// (or found again) its leader, a command the vehicle rejected. `kind` is a short word.
struct VehicleEventMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double sim_time_s = 0.0;
  std::string kind;
  std::string detail;
};

/// Checks a driver command: empty if valid, else which field is wrong and why (NaN, out of
/// range). Vehicles apply only valid commands; the recorder marks the others rejected.
std::string validate_command(const DriverCommandMsg& cmd);

/// Message type and stable name of each data topic, and the topic of each message type.
template <Topic T>
struct TopicTraits;
template <typename Msg>
struct TopicOf;
#define SYNDDS_TOPIC(TOPIC, MSG)                                     \
  template <>                                                        \
  struct TopicTraits<Topic::TOPIC> {                                 \
    using Msg = MSG;                                                 \
    static constexpr const char* name = #TOPIC;                      \
  };                                                                 \
  template <>                                                        \
  struct TopicOf<MSG> {                                              \
    static constexpr Topic value = Topic::TOPIC;                     \
  };
SYNDDS_TOPIC(vehicle_state, VehicleStateMsg)
SYNDDS_TOPIC(driver_command, DriverCommandMsg)
SYNDDS_TOPIC(terrain_deformation, TerrainDeformationMsg)
SYNDDS_TOPIC(terrain_snapshot, TerrainSnapshotMsg)
SYNDDS_TOPIC(collision_event, CollisionEventMsg)
SYNDDS_TOPIC(gps_fix, GpsFixMsg)
SYNDDS_TOPIC(imu, ImuMsg)
SYNDDS_TOPIC(magnetometer, MagnetometerMsg)
SYNDDS_TOPIC(wheel_speeds, WheelSpeedsMsg)
SYNDDS_TOPIC(image, ImageMsg)
SYNDDS_TOPIC(point_cloud, PointCloudMsg)
SYNDDS_TOPIC(v2v_message, V2VMessageMsg)
SYNDDS_TOPIC(vehicle_event, VehicleEventMsg)
#undef SYNDDS_TOPIC

/// Calls f(std::integral_constant<Topic, T>{}) for every data topic, in enum order.
template <typename F>
void for_each_topic(F&& f) {
  [&]<std::size_t... I>(std::index_sequence<I...>) {
    (f(std::integral_constant<Topic, kAllDataTopics[I]>{}), ...);
  }(std::make_index_sequence<std::size(kAllDataTopics)>{});
}

/// One manifest entry: member `writer` wrote `count` samples on `topic` with key `key`.
struct TopicCount {
  Topic topic = Topic::vehicle_state;
  std::string key;
  std::string writer;
  std::uint32_t count = 0;
  bool operator==(const TopicCount&) const = default;
};
using Manifest = std::vector<TopicCount>;

struct MemberAnnounceMsg {
  std::string member_id;
  MemberKind kind = MemberKind::vehicle;
  std::string run_id;
  std::string participant_guid;
  std::string host;
  std::int32_t pid = 0;
  std::int32_t protocol_version = kProtocolVersion;
  std::uint64_t config_fingerprint = 0;
  std::vector<std::string> expected_members;  // filled by the coordinator only
};

struct FrameGrantMsg {
  std::int64_t frame = 0;
  double sim_time_s = 0.0;  // end time of the granted frame
  Manifest manifest;        // what was published in frame - 1
  std::vector<std::string> joiners;  // late joiners taking part from frame + 1 on
  std::vector<std::string> departed;  // members lost under on_member_loss: continue since the previous grant
};

struct FrameDoneMsg {
  std::string member_id;
  std::int64_t frame = 0;
  Manifest published;
  double compute_s = 0.0;   // wall time the member spent in its step
  bool finished = false;    // true: reply to RunControl stop, the member is shutting down
  std::string error;        // non-empty: the member failed (and exits); the run aborts with it
};

struct MemberStatsMsg {
  std::string member_id;
  double mean_response_s = 0.0;  // grant sent -> done received, mean over frames
  double max_response_s = 0.0;
  double mean_compute_s = 0.0;   // member-reported step time
  std::uint64_t slowest_count = 0;  // frames in which this member answered last
  bool lost = false;
};

enum class RunStatus : std::uint8_t { completed, aborted };
std::string_view to_string(RunStatus status);

struct RunStatsMsg {
  std::uint64_t frames = 0;      // frames granted and completed
  std::int64_t final_frame = -1;
  double sim_time_s = 0.0;
  double wall_time_s = 0.0;
  double real_time_factor = 0.0;  // wall / sim; lower is faster
  std::vector<MemberStatsMsg> members;
};

struct RunControlMsg {
  RunStatus status = RunStatus::completed;  // completed = stop after final frame
  std::string reason;
  std::int64_t final_frame = -1;
  Manifest final_manifest;  // what was published in final_frame
  RunStatsMsg stats;
};

}  // namespace syndds::proto
