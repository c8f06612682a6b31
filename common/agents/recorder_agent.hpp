#pragma once
// The recorder member: writes the run directory as the run goes, through the run-directory
// writer (record/run_files.hpp). Every frame is written to all files as one unit as soon as it
// is complete, so a failure anywhere else loses nothing that was complete, and a failure of the
// recorder itself (a full disk) fails the frame, which ends the run with the reason. summary.json
// is rewritten (atomically) about once a second while the run goes on, so a recorder that is
// killed still says how far it got. Files (docs/outputs.md): vehicles.csv, commands.csv,
// events.csv, wheels.csv, scene.json, radar.csv (with radars), summary.json, summary.txt, with followers convoy.json and
// metrics.json, and on deformable terrain terrain_changes.csv, terrain_height.png,
// terrain_rut.png, terrain_images.json. The files the scenario's `recorder.skip` names are
// neither written nor subscribed to.
#include <chrono>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>

#include "agents/soil_routing.hpp"
#include "convoy/convoy_report.hpp"
#include "metrics/deviation.hpp"
#include "protocol/agent.hpp"
#include "record/run_files.hpp"
#include "scenario/scenario.hpp"
#include "scm/scm_terrain.hpp"

namespace syndds::record {

struct RecorderOptions {
  std::string output_dir;
  std::string run_id;
  std::string mode = "distributed";  // or "single-process"
  /// Continue the files of a checkpointed run in output_dir (load_state cuts them back to the
  /// checkpoint) instead of creating them.
  bool resume = false;
};

/// Per-vehicle totals accumulated from the recorded states.
struct VehicleTotals {
  double distance_m = 0.0;
  double speed_sum_mps = 0.0;
  double max_speed_mps = 0.0;
  std::uint64_t samples = 0;
  std::uint64_t collisions = 0;                 // with obstacles
  std::map<std::string, std::uint64_t> events;  // vehicle events by kind (leader_lost, ...,
                                                // kVehicleContact)
  Vec3 last_position = Vec3::Zero();
  double mean_speed_mps() const { return samples ? speed_sum_mps / samples : 0.0; }
  std::uint64_t vehicle_contacts() const;
};
/// The kind under which VehicleTotals::events counts contacts with other vehicles.
inline constexpr const char* kVehicleContact = "vehicle_contact";
inline std::uint64_t VehicleTotals::vehicle_contacts() const {
  const auto it = events.find(kVehicleContact);
  return it == events.end() ? 0 : it->second;
}

/// The paper's deviation metrics of one follower (metrics.json), computed when the run ends.
struct FollowerMetrics {
  std::string follower;
  metrics::ChainLink chain;  // the leader it is compared with, the vehicle it follows
  metrics::Deviations deviations;
  std::uint64_t obstacles_hit = 0;
  std::uint64_t vehicle_contacts = 0;  // collision episodes with other vehicles
  double follower_start_time_s = 0.0;  // start clip (on the follower's track)
  double leader_end_time_s = 0.0;      // end clip (on the leader's track)
  // Against the vehicle it follows (convoy report): smallest bumper gap, time below standstill.
  double min_bumper_gap_m = 0.0;
  double time_below_standstill_s = 0.0;
};

/// A member that left the run under on_member_loss: continue (it took no part from `frame` on).
struct MemberLoss {
  std::string member;
  std::int64_t frame = 0;
  double time_s = 0.0;
};

/// A participant the coordinator refused as a member (docs/protocol.md, "Admission"): a second
/// copy of a member, or anybody writing in a member's name. Not part of the checkpointed state:
/// it happened in wall time, not in the simulation, and survives a rollback.
struct Intrusion {
  std::string member;
  std::string participant;
  std::string what;
  std::int64_t frame = 0;  // the frame whose grant carried it
};

class RecorderAgent final : public proto::Agent {
 public:
  RecorderAgent(const scenario::Scenario& scenario, RecorderOptions options);
  RecorderAgent(const RecorderAgent&) = delete;
  RecorderAgent& operator=(const RecorderAgent&) = delete;

  const std::string& member_id() const override { return member_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::recorder; }
  std::vector<proto::Subscription> subscriptions() const override;
  /// With soil routing the recorder keeps the whole soil for the vehicles: the tiles a
  /// vehicle's box gains (terrain_patch, replay) and the late joiners' snapshots.
  std::vector<proto::Topic> publications() const override;
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;
  void finish(const proto::RunEnd& end, const proto::FrameSamples& final_inputs) override;
  /// Checkpoints: every file's length and the totals and tracks gathered so far; loading cuts
  /// the files back to those lengths, so nothing is written twice.
  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  /// Records an event that does not travel as a sample (e.g. a lost member seen locally).
  /// Throws record::WriteError if events.csv cannot be written.
  void note_event(std::int64_t frame, const std::string& kind, const std::string& vehicle,
                  const std::string& detail);

  const std::map<std::string, VehicleTotals>& totals() const { return totals_; }
  /// The convoy report (one entry per follower), computed when the run ends.
  const std::vector<convoy::FollowerReport>& convoy_report() const { return convoy_; }
  /// The deviation metrics (one entry per follower, in scenario order), computed when the run
  /// ends.
  const std::vector<FollowerMetrics>& follower_metrics() const { return metrics_; }
  /// Every vehicle's recorded track (kept only when the scenario has followers).
  const std::map<std::string, convoy::Track>& tracks() const { return tracks_; }
  /// The last frame whose samples are completely on disk (-1: none yet).
  std::int64_t last_recorded_frame() const { return last_frame_; }
  const std::vector<MemberLoss>& losses() const { return losses_; }
  const std::vector<Intrusion>& intrusions() const { return intrusions_; }

 private:
  void record(const proto::FrameSamples& samples, std::int64_t frame);
  /// terrain_changes.csv: the soil vertices changed since the last snapshot, at `frame`.
  void record_terrain_changes(std::int64_t frame);
  void record_sensors(const proto::FrameSamples& samples);
  /// radar.csv: one row per detection, with its world position.
  void record_radar(const proto::FrameSamples& samples);
  /// Writes the rows gathered since the last commit, in every file, as one unit.
  void commit();
  void count_routed(const proto::FrameSamples& samples);
  void keep_soil(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
                 proto::FrameSamples& outputs);
  void write_summary(const proto::RunControlMsg* end);
  void write_convoy_report();
  void write_metrics();
  /// The CSV files in a fixed order (null: not written by this scenario).
  std::vector<CsvFile*> files() const;
  /// Runs `write`; a WriteError marks the recorder failed (every later frame fails too).
  template <typename F>
  void guarded(F&& write);

  std::string member_id_ = scenario::kRecorderMember;
  RecorderOptions options_;
  std::string scenario_name_;
  std::string scenario_file_;
  double heartbeat_s_;
  std::vector<std::string> vehicle_ids_;
  std::vector<std::string> members_;
  std::map<std::string, std::string> vehicle_of_member_;  // "controller/a" -> "a"
  std::unique_ptr<CsvFile> vehicles_;
  std::unique_ptr<CsvFile> commands_;
  std::unique_ptr<CsvFile> events_;
  std::unique_ptr<CsvFile> wheels_;  // every wheel's pose and spin, every frame (replay)
  std::unique_ptr<CsvFile> terrain_changes_;  // deformable terrain: soil heights at intervals
  std::int64_t terrain_every_ = 1;             // frames between terrain_changes.csv snapshots
  std::set<std::pair<std::int32_t, std::int32_t>> changed_vertices_;  // (j, i) since then
  // Interoceptive sensor samples (only when some vehicle carries such sensors).
  std::unique_ptr<CsvFile> gps_;
  std::unique_ptr<CsvFile> imu_;
  std::unique_ptr<CsvFile> compass_;
  std::unique_ptr<CsvFile> wheel_speeds_;
  std::unique_ptr<CsvFile> v2v_;  // only when some vehicle broadcasts V2V messages
  std::unique_ptr<CsvFile> radar_;  // only when some vehicle carries a radar
  // Convoys: (follower, vehicle followed) pairs and every vehicle's track, for the report.
  std::vector<std::pair<std::string, std::string>> followers_;
  std::map<std::string, convoy::GapGeometry> gap_geometry_;  // per follower: boxes, standstill
  std::map<std::string, convoy::Track> tracks_;
  std::vector<convoy::FollowerReport> convoy_;
  std::map<std::string, metrics::ChainLink> chains_;  // per follower
  std::vector<FollowerMetrics> metrics_;
  std::map<std::string, metrics::SpeedSummary> leaders_;  // heads of the follow chains
  std::map<std::string, VehicleTotals> totals_;
  std::unique_ptr<scm::ScmTerrain> soil_;  // a copy of the deformable terrain, for the images
  bool routing_ = false;                   // terrain.scm.routing: the soil keeper too
  std::map<std::string, std::uint64_t> routed_bytes_;  // packed, by destination vehicle
  agents::SoilBoxes soil_boxes_;                 // the routed vehicles' boxes
  std::uint64_t terrain_bytes_ = 0;        // vertex lists received, packed as they travel
  std::uint64_t terrain_vertices_ = 0;     // vertex records received
  std::uint64_t terrain_max_frame_bytes_ = 0;
  std::int64_t last_frame_ = -1;     // on disk, complete
  std::int64_t pending_frame_ = -1;  // gathered, not yet committed
  std::vector<MemberLoss> losses_;
  std::vector<Intrusion> intrusions_;
  std::string failure_;  // the write error that stopped the recorder
  std::unique_ptr<SpaceReserve> reserve_;  // room for the final summary on a full disk
  std::chrono::steady_clock::time_point started_;
  std::chrono::steady_clock::time_point summary_written_;
  bool finished_ = false;
};

}  // namespace syndds::record
