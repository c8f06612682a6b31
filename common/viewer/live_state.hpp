#pragma once
// What a live viewer knows of a run under way, fed from samples as they arrive and read by any
// number of browser connections, each at its own pace. Latest-only by design: a vehicle's
// newest state replaces the one before; the soil keeps each vertex's newest height with a
// change number; a connection asks for "everything newer than my cursor" whenever it is ready
// to send again, so a slow browser gets fewer, larger updates and never a growing queue, and
// the feeding side never waits for a browser. No DDS here (services/viewer feeds it).
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "protocol/messages.hpp"

namespace syndds::viewer {

/// Where one connection is: the change numbers it has already been sent.
struct Cursor {
  std::uint64_t terrain = 0;   // soil changes up to this number were sent
  std::uint64_t vehicles = 0;  // vehicle states up to this number were sent
  std::uint64_t members = 0;
  std::uint64_t status = 0;   // status changes up to this number were sent
  std::uint64_t contacts = 0;  // contact marks up to this number were sent
  std::uint64_t radar = 0;     // radar scans up to this change number were sent
  std::int64_t frame = -2;    // the frame last sent (-2: nothing sent yet)
};

class LiveState {
 public:
  /// Newest state of a vehicle (older frames than the one held are ignored).
  void on_vehicle_state(const proto::VehicleStateMsg& s);
  /// Soil vertices as a deformation list carries them (their new surface heights).
  void on_terrain(const std::vector<proto::TerrainVertexMsg>& vertices);
  /// A frame granted by the coordinator at wall time `wall_s` (any monotonic seconds).
  void on_frame(std::int64_t frame, double sim_time_s, double wall_s);
  /// A collision began (with an obstacle or another vehicle): a mark at its point. The newest
  /// kMaxContactMarks are kept for connections that come later.
  void on_collision(const proto::CollisionEventMsg& e);
  static constexpr std::size_t kMaxContactMarks = 256;
  /// A radar's scan: it replaces the scan held for its (vehicle, sensor) unless it is older
  /// (an earlier stamp time); a scan without detections clears that radar's detections. Each
  /// detection is kept at its world position (the scan's pose applied to its sensor-frame
  /// x, y, z) with its radial speed and strength. Bounded: scans of at most kMaxRadarSensors
  /// (vehicle, sensor) pairs (a scan of a further pair is dropped), and of each scan its first
  /// kMaxRadarDetections detections (a scan lists them by range: the nearest).
  void on_radar(const proto::RadarScanMsg& m);
  static constexpr std::size_t kMaxRadarSensors = 64;
  static constexpr std::size_t kMaxRadarDetections = 256;
  /// A member announced itself.
  void on_member(const proto::MemberAnnounceMsg& m, double wall_s);
  /// The run ended (completed or aborted).
  void on_run_end(const proto::RunControlMsg& c);

  /// One update for a connection at `cursor` as a JSON text: the run's progress and real-time
  /// factor, every vehicle whose state changed, the contact marks not sent yet, the radar scans
  /// that changed (docs/viewer.md, "Radar"), at most `max_vertices` soil vertices changed
  /// since the cursor ([i, j, height] triples, oldest change first), the member list when it
  /// changed; the cursor moves past what was put in. `more` is set when soil changes remain.
  std::string update(Cursor& cursor, std::size_t max_vertices, bool* more = nullptr);

  /// Whether an update for `cursor` would carry anything new (a frame, a state, a contact mark, a
  /// radar scan, soil, members, the status): a connection with nothing new sends nothing.
  bool has_news(const Cursor& cursor) const;

  std::int64_t frame() const;
  /// The run's end was seen (RunControl).
  bool ended() const;
  std::size_t soil_vertices() const;
  /// Soil changes kept (at most about twice the vertices; older duplicates are dropped).
  std::size_t soil_log_size() const;
  /// Radar scans held: one per (vehicle, sensor).
  std::size_t radar_scans() const;

 private:
  struct Vehicle {
    proto::VehicleStateMsg state;
    std::uint64_t change = 0;
  };
  struct Vertex {
    std::int32_t i = 0, j = 0;
    double height = 0.0;
    std::uint64_t change = 0;
  };
  struct Member {
    std::string kind, host;
    std::int32_t pid = 0;
  };
  void compact_soil();
  struct ContactMark {
    std::uint64_t number = 0;  // 1, 2, ... in arrival order
    proto::CollisionEventMsg event;
  };
  std::deque<ContactMark> contacts_;
  std::uint64_t contact_changes_ = 0;
  struct RadarDetection {
    Vec3 at = Vec3::Zero();  // world frame
    float radial_speed_mps = 0, strength_db = 0;
  };
  struct RadarScan {
    std::int64_t frame = 0;
    double time_s = 0.0;  // the scan's stamp time
    std::vector<RadarDetection> detections;
    std::uint64_t change = 0;
  };
  std::map<std::pair<std::string, std::string>, RadarScan> radar_;  // by (vehicle, sensor)
  std::uint64_t radar_changes_ = 0;

  mutable std::mutex mutex_;
  std::map<std::string, Vehicle> vehicles_;
  std::uint64_t vehicle_changes_ = 0;
  std::unordered_map<std::uint64_t, Vertex> soil_;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> soil_log_;  // (change, vertex key)
  std::uint64_t soil_changes_ = 0;
  std::map<std::string, Member> members_;
  std::uint64_t member_changes_ = 0;
  std::int64_t frame_ = -1;
  double sim_time_s_ = 0.0;
  // Real-time factor (wall / sim) over the frames of the last seconds.
  std::deque<std::pair<double, double>> recent_;  // (wall_s, sim_s)
  std::string status_ = "running";
  std::uint64_t status_changes_ = 1;
  std::string reason_;
};

}  // namespace syndds::viewer
