#pragma once
// The convoy follower member (controller/<id> with `controller: {type: follower}`): reads its
// vehicle's own GPS, compass and wheel-speed samples and the V2V messages of the vehicle it
// follows (and with `radar:` its own radar's scans), all stamped k-1, and publishes the DriverCommand stamped k, plus a VehicleEvent when
// it loses or finds again its leader. Never reads a true vehicle state.
#include "convoy/follower.hpp"
#include "protocol/agent.hpp"
#include "scenario/scenario.hpp"

namespace syndds::agents {

/// What a convoy follower knows of its own vehicle and, from the scenario, of the one it
/// follows and of its trail's source (either may be null): dimensions, not states.
convoy::FollowerVehicle follower_vehicle(const scenario::VehicleConfig& own,
                                         const scenario::VehicleConfig* leader,
                                         const scenario::VehicleConfig* trail_source = nullptr);
/// The follower converts latitude / longitude with its own (first) GPS's origin and model.
sensors::GeodeticConverter follower_converter(const scenario::VehicleConfig& v);

class FollowerAgent final : public proto::Agent {
 public:
  FollowerAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& vehicle);

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::controller; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override {
    return {proto::Topic::driver_command, proto::Topic::vehicle_event};
  }
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;

  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  const convoy::ConvoyFollower& follower() const { return follower_; }

 private:
  std::string vehicle_id_;
  std::string leader_id_;
  std::string trail_of_;  // the trail's source when not the leader (controller trail: head)
  std::string member_id_;
  convoy::ConvoyFollower follower_;
  bool radar_ = false;  // reads its own radar's scans (controller radar.sensor)
};

}  // namespace syndds::agents
