#pragma once
// Plain C++ mirrors of the IDL types in idl/syndds.idl. common/ code speaks these; the DDS
// layer (services/dds) converts them to and from the generated types at the edge.
//
// Frame convention (see docs/protocol.md): frame k ends at sim time t_k = k * heartbeat_s.
// Frame 0 is the initial frame (vehicles publish their initial state, nothing steps); in frame
// k >= 1 vehicles advance from t_{k-1} to t_k. A sample "stamped k" was produced in frame k.
//
// Each message is defined once: its struct, its field list (SYNDDS_FIELDS, right after it) and
// its IDL type. Everything else (the conversions to and from the IDL types, FrameSamples, the
// topic names, the DDS types and QoS of each topic) comes from these lists. Adding a field: the
// member, its name in the field list and the member in idl/syndds.idl. Adding a data topic: the
// struct and its field list, a row in SYNDDS_DATA_TOPICS and the IDL type (docs/protocol.md).
// Every sample repeats its header (vehicle_id, source, frame) rather than inheriting it: agents
// build samples by aggregate initialisation ({vehicle, source, frame, ...}), which a base struct
// would break, and the IDL spells the header out in each type too.
#include <cstdint>
#include <string>
#include <iterator>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "core/hash.hpp"
#include "core/math.hpp"
#include "protocol/fields.hpp"

namespace syndds::proto {

inline constexpr std::int32_t kProtocolVersion = 6;
/// The files of two fingerprints ("ROLE HASH" lines) that differ: "ROLE (HASH here, HASH
/// there)", or "ROLE (only here)" / "(only there)", joined by "; ". Empty when either list is
/// empty (a peer that sends none) or they agree.
std::string config_file_differences(const std::vector<std::string>& mine,
                                    const std::vector<std::string>& theirs);
/// A scenario fingerprint as every log shows it (16 hex digits).
inline std::string fingerprint_hex(std::uint64_t f) {
  return hex64(f);
}
/// Ends every fingerprint-mismatch message: how to find the file that differs.
inline constexpr const char* kFingerprintHint =
    "to find the file that differs, compare the 'files:' line each process logs at startup, or "
    "run syndds_plan SCENARIO --format files on both hosts";

enum class MemberKind : std::uint8_t { vehicle, controller, recorder, sensor, external, coordinator };
std::string_view to_string(MemberKind kind);

/// The data topics (those that take part in the frame manifest), one row each:
///   X(topic, message struct, IDL type, FrameSamples list, samples per key and frame)
/// `topic` is the stable short name used in manifests, logs and DDS topic names; the last column
/// is how many samples one writer may write of one key in one frame: the DDS writer keeps twice
/// that (two frames are in flight at most), so no sample a barrier member still needs is ever
/// replaced. Sensors: the scenario checks their rates against it when it loads. Collisions: one
/// per obstacle and contact episode, and a vehicle may touch many obstacles in one frame.
#define SYNDDS_DATA_TOPICS(X)                                                               \
  X(vehicle_state, VehicleStateMsg, VehicleState, vehicle_states, 4)                        \
  X(driver_command, DriverCommandMsg, DriverCommand, driver_commands, 4)                    \
  X(terrain_deformation, TerrainDeformationMsg, TerrainDeformation, terrain_deformations, 4) \
  X(terrain_snapshot, TerrainSnapshotMsg, TerrainSnapshot, terrain_snapshots, 4)            \
  X(collision_event, CollisionEventMsg, CollisionEvent, collision_events, 256)              \
  X(gps_fix, GpsFixMsg, GpsFix, gps_fixes, 32)                                              \
  X(imu, ImuMsg, Imu, imus, 32)                                                             \
  X(magnetometer, MagnetometerMsg, Magnetometer, magnetometers, 32)                         \
  X(wheel_speeds, WheelSpeedsMsg, WheelSpeeds, wheel_speeds, 32)                            \
  X(image, ImageMsg, Image, images, 4)                                                      \
  X(point_cloud, PointCloudMsg, PointCloud, point_clouds, 4)                                \
  X(v2v_message, V2VMessageMsg, V2VMessage, v2v_messages, 32)                               \
  X(vehicle_event, VehicleEventMsg, VehicleEvent, vehicle_events, 256)                      \
  X(radar, RadarScanMsg, RadarScan, radar_scans, 4)                                        \
  X(soil_interest, SoilInterestMsg, SoilInterest, soil_interests, 4)                        \
  X(terrain_patch, TerrainPatchMsg, TerrainPatch, terrain_patches, 4)

/// The protocol messages (not data topics), one row each: X(message struct, IDL type).
#define SYNDDS_PROTOCOL_MESSAGES(X)          \
  X(MemberAnnounceMsg, MemberAnnounce)       \
  X(FrameGrantMsg, FrameGrant)               \
  X(FrameDoneMsg, FrameDone)                 \
  X(FrameDonesMsg, FrameDones)               \
  X(RunControlMsg, RunControl)

#define SYNDDS_TOPIC_ENUM_(TOPIC, MSG, IDL, LIST, PER_FRAME) TOPIC,
enum class Topic : std::uint8_t { SYNDDS_DATA_TOPICS(SYNDDS_TOPIC_ENUM_) };
#undef SYNDDS_TOPIC_ENUM_
#define SYNDDS_TOPIC_ENUM_(TOPIC, MSG, IDL, LIST, PER_FRAME) Topic::TOPIC,
inline constexpr Topic kAllDataTopics[] = {SYNDDS_DATA_TOPICS(SYNDDS_TOPIC_ENUM_)};
#undef SYNDDS_TOPIC_ENUM_
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
SYNDDS_FIELDS(WheelStateMsg, pose, spin_rad_s, steer_angle_rad, vertical_load_n)

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
SYNDDS_FIELDS(VehicleStateMsg, vehicle_id, source, frame, sim_time_s, pose, linear_velocity,
              angular_velocity, linear_acceleration, angular_acceleration, wheels, steering,
              throttle, braking, gear, engine_speed_rpm)

struct DriverCommandMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double steering = 0.0;  // [-1, 1], positive turns left
  double throttle = 0.0;  // [0, 1]
  double braking = 0.0;   // [0, 1]
};
SYNDDS_FIELDS(DriverCommandMsg, vehicle_id, source, frame, steering, throttle, braking)

struct TerrainVertexMsg {
  std::int32_t i = 0;
  std::int32_t j = 0;
  double height = 0.0;           // current surface level
  double level_initial = 0.0;    // undeformed level incl. bulldozed material
  double sinkage_plastic = 0.0;  // permanent sinkage below level_initial
  double sigma_yield = 0.0;      // highest Bekker stress reached
};
SYNDDS_FIELDS(TerrainVertexMsg, i, j, height, level_initial, sinkage_plastic, sigma_yield)

struct TerrainDeformationMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  std::uint32_t source_index = 0;  // the writer's rank in the member list (merge tie-break)
  double spacing_m = 0.0;
  std::vector<TerrainVertexMsg> vertices;
};
SYNDDS_FIELDS(TerrainDeformationMsg, vehicle_id, source, frame, source_index, spacing_m, vertices)

/// Every stored vertex of one vehicle's terrain copy at the end of `frame` (late joiners).
struct TerrainSnapshotMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double spacing_m = 0.0;
  std::vector<TerrainVertexMsg> vertices;
};
SYNDDS_FIELDS(TerrainSnapshotMsg, vehicle_id, source, frame, spacing_m, vertices)

/// Soil routing (docs/scm.md, "Routing"): the tiles of 32 x 32 vertices (inclusive index box)
/// whose records vehicle `vehicle_id` receives, as terrain_patch samples, from the next frame
/// on. Written in frame 0 and in every frame where the box changes.
struct SoilInterestMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  std::int32_t tile_i_lo = 0;
  std::int32_t tile_i_hi = -1;
  std::int32_t tile_j_lo = 0;
  std::int32_t tile_j_hi = -1;
};
SYNDDS_FIELDS(SoilInterestMsg, vehicle_id, source, frame, tile_i_lo, tile_i_hi, tile_j_lo,
              tile_j_hi)

/// Soil routing: vertex records addressed to vehicle `vehicle_id` (the key is the destination).
/// Live (replay false): the writer's changes of `frame` inside the destination's box, merged by
/// the sync rule like a terrain_deformation list. Replay (written by the soil keeper, the
/// recorder): every stored vertex of the tiles the destination added to its box in frame - 1,
/// as the whole soil was after the lists of that frame; it replaces what the destination held
/// there.
struct TerrainPatchMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  std::uint32_t source_index = 0;  // the writer's rank in the member list (merge tie-break)
  double spacing_m = 0.0;
  bool replay = false;
  std::vector<TerrainVertexMsg> vertices;
};
SYNDDS_FIELDS(TerrainPatchMsg, vehicle_id, source, frame, source_index, spacing_m, replay,
              vertices)

/// The start of a collision episode of `vehicle_id`: with a static obstacle (obstacle_id) or
/// with another vehicle (other_vehicle_id; each of the two vehicles reports its own event).
struct CollisionEventMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  double sim_time_s = 0.0;
  std::string obstacle_id;
  double impulse_ns = 0.0;
  Vec3 position = Vec3::Zero();
  std::string other_vehicle_id;
  double relative_speed_mps = 0.0;  // vehicle contacts: contact point speed relative to the other's
};
SYNDDS_FIELDS(CollisionEventMsg, vehicle_id, source, frame, sim_time_s, obstacle_id, impulse_ns,
              position, other_vehicle_id, relative_speed_mps)

/// A vehicle's collision state at the end of a frame, for the other vehicles' contact step
/// (docs/vehicle-contact.md). Not a data topic: it travels with the barrier, in the member's
/// FrameDone and, for vehicles near another one, in the next FrameGrant.
struct VehicleBodyMsg {
  std::string vehicle_id;
  Pose pose;                            // chassis reference frame in the world
  Vec3 linear_velocity = Vec3::Zero();  // of the reference point, world frame
  Vec3 angular_velocity = Vec3::Zero();
  std::vector<Pose> wheels;             // wheel centres, FL FR RL RR
  double footprint_offset_m = 0.0;      // the footprint rectangle (vehicle::Footprint)
  double footprint_half_length_m = 0.0;
  double footprint_half_width_m = 0.0;
};
SYNDDS_FIELDS(VehicleBodyMsg, vehicle_id, pose, linear_velocity, angular_velocity, wheels,
              footprint_offset_m, footprint_half_length_m, footprint_half_width_m)

/// Stamp of a synthetic sensor sample: which sensor, its sample number, when it was measured
/// and when it became available (measurement time + modelled lag).
struct SensorStampMsg {
  std::string sensor_id;
  std::uint64_t sequence = 0;
  double time_s = 0.0;
  double available_s = 0.0;
};
SYNDDS_FIELDS(SensorStampMsg, sensor_id, (sequence, number), time_s, available_s)

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
SYNDDS_FIELDS(GpsFixMsg, vehicle_id, source, frame, stamp, latitude_deg, longitude_deg, altitude_m,
              enu_m)

struct ImuMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  Vec3 accel_mps2 = Vec3::Zero();  // specific force in the sensor frame (at rest: +g up)
  Vec3 gyro_rad_s = Vec3::Zero();
};
SYNDDS_FIELDS(ImuMsg, vehicle_id, source, frame, stamp, accel_mps2, gyro_rad_s)

struct MagnetometerMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  double heading_rad = 0.0;  // compass heading, clockwise from true north, [0, 2 pi)
  Vec3 field_ut = Vec3::Zero();
};
SYNDDS_FIELDS(MagnetometerMsg, vehicle_id, source, frame, stamp, heading_rad, field_ut)

struct WheelSpeedsMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  std::vector<double> wheel_spin_rad_s;  // FL, FR, RL, RR
};
SYNDDS_FIELDS(WheelSpeedsMsg, vehicle_id, source, frame, stamp, wheel_spin_rad_s)

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
SYNDDS_FIELDS(ImageMsg, vehicle_id, source, frame, stamp, pose, width, height, encoding, data)

struct PointMsg {
  float x = 0, y = 0, z = 0;  // sensor frame, metres
  float intensity = 0;
  float range = 0;
  std::uint16_t channel = 0;
  std::uint16_t sample = 0;
};
SYNDDS_FIELDS(PointMsg, x, y, z, intensity, range, channel, sample)

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
SYNDDS_FIELDS(PointCloudMsg, vehicle_id, source, frame, stamp, pose, channels, samples, points)

/// One radar detection (common/sensors/radar.hpp): a cluster of returns.
struct RadarDetectionMsg {
  float x = 0, y = 0, z = 0;   // centroid, sensor frame, metres
  float range_m = 0;
  float azimuth_rad = 0;       // from x towards y
  float elevation_rad = 0;     // up
  float radial_speed_mps = 0;  // range rate: > 0 moving away
  float strength_db = 0;       // received power re a 1 m^2 target at 1 m
  float rcs_dbsm = 0;          // radar cross-section, dB re 1 m^2
  std::uint32_t points = 0;    // returns clustered
};
SYNDDS_FIELDS(RadarDetectionMsg, x, y, z, range_m, azimuth_rad, elevation_rad, radial_speed_mps,
              strength_db, rcs_dbsm, points)

struct RadarScanMsg {
  std::string vehicle_id;
  std::string source;
  std::int64_t frame = 0;
  SensorStampMsg stamp;
  Pose pose;                            // radar pose in the world
  Vec3 velocity = Vec3::Zero();         // the radar's own velocity (world frame)
  std::vector<RadarDetectionMsg> detections;  // by range
};
SYNDDS_FIELDS(RadarScanMsg, vehicle_id, source, frame, stamp, pose, velocity, detections)

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
SYNDDS_FIELDS(V2VMessageMsg, vehicle_id, source, frame, (sequence, number), sensor_time_s,
              latitude_deg, longitude_deg, altitude_m, speed_mps, heading_rad)

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
SYNDDS_FIELDS(VehicleEventMsg, vehicle_id, source, frame, sim_time_s, kind, detail)

/// Checks a driver command: empty if valid, else which field is wrong and why (NaN, out of
/// range). Vehicles apply only valid commands; the recorder marks the others rejected.
std::string validate_command(const DriverCommandMsg& cmd);

/// Message type, stable name and samples per key and frame of each data topic, and the topic
/// of each message type.
template <Topic T>
struct TopicTraits;
template <typename Msg>
struct TopicOf;
#define SYNDDS_TOPIC_TRAITS_(TOPIC, MSG, IDL, LIST, PER_FRAME)         \
  template <>                                                        \
  struct TopicTraits<Topic::TOPIC> {                                 \
    using Msg = MSG;                                                 \
    static constexpr const char* name = #TOPIC;                      \
    static constexpr std::uint32_t max_per_frame = PER_FRAME;        \
  };                                                                 \
  template <>                                                        \
  struct TopicOf<MSG> {                                              \
    static constexpr Topic value = Topic::TOPIC;                     \
  };
SYNDDS_DATA_TOPICS(SYNDDS_TOPIC_TRAITS_)
#undef SYNDDS_TOPIC_TRAITS_

/// Addressed topics: a sample's key names the vehicle it is for, not the writer's vehicle, and a
/// writer may write to every vehicle in a frame (max_per_frame then counts per key). The only
/// one: terrain_patch (soil routing).
constexpr bool is_addressed(Topic t) { return t == Topic::terrain_patch; }

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
SYNDDS_FIELDS(TopicCount, topic, key, writer, count)
using Manifest = std::vector<TopicCount>;

struct MemberAnnounceMsg {
  std::string member_id;
  MemberKind kind = MemberKind::vehicle;
  std::string run_id;
  std::string participant_guid;
  std::string host;
  std::int32_t pid = 0;
  std::string process_key;  // "BOOT_ID/PID/START": tells a running process from a dead one
                            // on the same machine (core/process_watch.hpp); "" if unknown
  std::int32_t protocol_version = kProtocolVersion;
  std::uint64_t config_fingerprint = 0;
  std::vector<std::string> expected_members;  // filled by the coordinator only
  // The coordinator's word on who is which member (docs/protocol.md, "Admission"):
  std::vector<std::string> admitted;  // "MEMBER PARTICIPANT_GUID"
  std::vector<std::string> refused;   // "MEMBER PARTICIPANT_GUID why"
  std::string build_id;  // version+hash of the sources (core/build_identity.hpp); "": unchecked
  std::vector<std::string> config_files;  // "ROLE HASH" of each file in the fingerprint
  double join_timeout_s = 0.0;        // the coordinator's deadlines, for external members
  double frame_timeout_s = 0.0;
  std::int64_t checkpoint_every = 0;  // frames between the run's checkpoints (0: none)
};
SYNDDS_FIELDS(MemberAnnounceMsg, member_id, kind, run_id, participant_guid, host, pid,
              process_key, protocol_version, config_fingerprint, expected_members, admitted,
              refused, build_id, config_files, join_timeout_s, frame_timeout_s, checkpoint_every)

struct FrameGrantMsg {
  std::int64_t frame = 0;
  double sim_time_s = 0.0;  // end time of the granted frame
  Manifest manifest;        // what was published in frame - 1
  std::vector<std::string> joiners;  // late joiners taking part from frame + 1 on
  std::vector<std::string> departed;  // members lost under on_member_loss: continue since the previous grant
  std::uint32_t epoch = 0;  // +1 at every recovery (on_member_loss: recover)
  bool rollback = false;    // every member restores its checkpoint of `frame` (instead of
                            // stepping it) and reports it done; frame + 1 is granted next
  std::vector<std::string> rejoined;  // with rollback: "MEMBER PARTICIPANT_GUID" of each member
                                      // restarted since (its new participant)
  std::vector<std::string> intrusions;  // "MEMBER PARTICIPANT_GUID what": samples and claims the
                                        // coordinator refused since the previous grant
  std::vector<VehicleBodyMsg> bodies;   // of frame - 1, of the vehicles within reach of another
                                        // (select_contact_bodies), sorted by vehicle_id
};
SYNDDS_FIELDS(FrameGrantMsg, frame, sim_time_s, manifest, joiners, departed, epoch, rollback,
              rejoined, intrusions, bodies)

struct FrameDoneMsg {
  std::string member_id;
  std::int64_t frame = 0;
  Manifest published;
  double compute_s = 0.0;   // wall time the member spent in its step
  bool finished = false;    // true: reply to RunControl stop, the member is shutting down
  std::string error;        // non-empty: the member failed (and exits); the run aborts with it
  std::uint64_t checkpoint_bytes = 0;  // > 0: before this frame the member wrote its state of
                                       // frame - 1 (docs/checkpoints.md), this many bytes
  std::uint32_t epoch = 0;  // of the grant this answers: dones of an epoch rolled back are void
  std::vector<VehicleBodyMsg> body;  // a vehicle member's collision state after this frame
                                     // (at most one); empty for other members
};
SYNDDS_FIELDS(FrameDoneMsg, member_id, frame, published, compute_s, finished, error,
              checkpoint_bytes, epoch, body)

/// The regular dones of several members of one process for one grant, sent together
/// (DoneGather): the coordinator takes each as if it had come alone.
struct FrameDonesMsg {
  std::vector<FrameDoneMsg> dones;
};
SYNDDS_FIELDS(FrameDonesMsg, dones)

/// Checkpoints are written of every frame K that is a positive multiple of `every` frames
/// (every <= 0: never), by each member before it steps frame K + 1.
inline bool checkpoint_due(std::int64_t frame, std::int64_t every) {
  return every > 0 && frame > 0 && frame % every == 0;
}

struct MemberStatsMsg {
  std::string member_id;
  double mean_response_s = 0.0;  // grant sent -> done received, mean over frames
  double max_response_s = 0.0;
  double mean_compute_s = 0.0;   // member-reported step time
  std::uint64_t slowest_count = 0;  // frames in which this member answered last
  bool lost = false;
};
SYNDDS_FIELDS(MemberStatsMsg, member_id, mean_response_s, max_response_s, mean_compute_s,
              slowest_count, lost)

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
SYNDDS_FIELDS(RunStatsMsg, frames, final_frame, sim_time_s, wall_time_s, real_time_factor, members)

struct RunControlMsg {
  RunStatus status = RunStatus::completed;  // completed = stop after final frame
  std::string reason;
  std::int64_t final_frame = -1;
  Manifest final_manifest;  // what was published in final_frame
  RunStatsMsg stats;
};
SYNDDS_FIELDS(RunControlMsg, status, reason, final_frame, final_manifest, stats)

}  // namespace syndds::proto
