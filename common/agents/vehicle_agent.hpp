#pragma once
// The vehicle member: owns one dynamics model, applies the DriverCommand stamped k-1, steps
// steps_per_frame dynamics steps in frame k and publishes its VehicleState stamped k. When its
// controller is lost (on_member_loss: continue) it brakes to a stop instead of driving on with
// the last command.
#include <map>
#include <memory>

#include "agents/scm_messages.hpp"
#include "agents/soil_routing.hpp"
#include "convoy/v2v.hpp"
#include "protocol/agent.hpp"
#include "record/run_files.hpp"
#include "scm/scm_terrain.hpp"
#include "sensors/rig.hpp"
#include "scenario/scenario.hpp"
#include "vehicle/vehicle_model.hpp"

namespace syndds::agents {

/// Builds the dynamics model a vehicle entry of the scenario asks for, on the scenario's terrain
/// and among its obstacles. On SCM terrain pass the vehicle's copy of the soil as `scm`: the full
/// model takes its wheel forces from it and deforms it; the reduced model only rides on it.
std::unique_ptr<vehicle::VehicleModel> make_vehicle_model(
    const scenario::Scenario& scenario, const scenario::VehicleConfig& config,
    std::shared_ptr<scm::ScmTerrain> scm = nullptr);

/// The rank of a member in the scenario's member list: the tie-break of the SCM merge rule.
std::uint32_t member_rank(const scenario::Scenario& scenario, const std::string& member_id);

/// Checks a received command; returns an empty string if valid, else which field is wrong.
using proto::validate_command;

class VehicleAgent final : public proto::Agent {
 public:
  VehicleAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& vehicle);

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::vehicle; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override;
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;
  void note_rejected(const std::vector<proto::RejectedSample>& rejected) override;
  void finish(const proto::RunEnd& end, const proto::FrameSamples& final_inputs) override;
  /// Checkpoints: the dynamics, the soil copy, the sensors, V2V, what the vehicle knows of its
  /// controller.
  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  const vehicle::VehicleModel& model() const { return *model_; }
  std::uint64_t rejected_commands() const { return rejected_; }
  /// This vehicle's copy of the deformable terrain (null on rigid ground).
  const scm::ScmTerrain* soil() const { return soil_.get(); }
  /// Test aid: append "frame hash" of the soil grid at every frame boundary (after the other
  /// vehicles' changes of that frame were merged) to `file`.
  void log_terrain_hashes(const std::string& file);
  /// True once the member that drives this vehicle was lost (it is braking to a stop).
  bool controller_lost() const { return controller_lost_; }

 private:
  proto::VehicleStateMsg state_message(const vehicle::VehicleSnapshot& s, std::int64_t frame,
                                       double sim_time_s) const;
  /// This vehicle's collision state in `s`, for the others' contact step.
  proto::VehicleBodyMsg body_message(const vehicle::VehicleSnapshot& s) const;
  /// The other vehicles within reach among the bodies of frame k-1, to the model.
  void set_peers(const std::vector<proto::VehicleBodyMsg>& bodies);
  void note_departed(const proto::FrameContext& ctx, proto::FrameSamples& outputs);
  /// Start of a frame on soil: the interest square, then the others' records of frame k-1.
  void merge_soil(const proto::FrameContext& ctx, const proto::FrameSamples& inputs);
  /// End of a frame on soil: this frame's changes to whoever needs them.
  void publish_soil(const proto::FrameContext& ctx, proto::FrameSamples& outputs);

  std::string vehicle_id_;
  std::string member_id_;
  double heartbeat_s_;
  double step_s_;
  std::int64_t steps_per_frame_;
  std::shared_ptr<scm::ScmTerrain> soil_;
  std::unique_ptr<sensors::VehicleSensors> sensors_;  // interoceptive sensors, if any
  std::unique_ptr<convoy::V2VBroadcaster> v2v_;       // V2V broadcasts, if configured
  std::uint32_t rank_ = 0;
  double spacing_m_ = 0.0;
  bool snapshot_provider_ = false;  // writes the terrain snapshot late joiners start from
  // Soil routing (terrain.scm.routing): this vehicle's box and the others'.
  std::optional<SoilSubscription> subscription_;
  SoilBoxes peer_boxes_;
  std::uint64_t routed_live_ = 0;      // records received (log only)
  std::uint64_t routed_replayed_ = 0;
  std::uint64_t routed_bytes_ = 0;     // packed, as they travel
  std::unique_ptr<vehicle::VehicleModel> model_;
  vehicle::Footprint footprint_;
  // Every vehicle of the scenario (this one too): the shapes of the bodies it may meet.
  std::map<std::string, std::shared_ptr<const vehicle::VehicleParams>> vehicle_params_;
  std::uint64_t rejected_ = 0;
  std::size_t max_deferred_ = 0;  // most soil vertices held aside by interest management
  std::vector<proto::RejectedSample> intrusions_;  // refused by the transport, not yet reported
  std::string controller_;  // the member that writes our driver commands (empty: none)
  bool controller_lost_ = false;
  std::unique_ptr<record::OutputFile> hash_log_;
};

}  // namespace syndds::agents
