#pragma once
// Conversions between the plain structs of common/protocol and the fastddsgen types. Incoming
// samples are validated here: a malformed sample raises ProtocolError naming the field.
#include <syndds.h>

#include "protocol/messages.hpp"

namespace syndds::dds {

msg::MemberAnnounce to_dds(const proto::MemberAnnounceMsg& m);
proto::MemberAnnounceMsg from_dds(const msg::MemberAnnounce& m);

msg::FrameGrant to_dds(const proto::FrameGrantMsg& m);
proto::FrameGrantMsg from_dds(const msg::FrameGrant& m);

msg::FrameDone to_dds(const proto::FrameDoneMsg& m);
proto::FrameDoneMsg from_dds(const msg::FrameDone& m);

msg::RunControl to_dds(const proto::RunControlMsg& m);
proto::RunControlMsg from_dds(const msg::RunControl& m);

msg::VehicleState to_dds(const proto::VehicleStateMsg& m);
proto::VehicleStateMsg from_dds(const msg::VehicleState& m);

msg::DriverCommand to_dds(const proto::DriverCommandMsg& m);
proto::DriverCommandMsg from_dds(const msg::DriverCommand& m);

msg::TerrainDeformation to_dds(const proto::TerrainDeformationMsg& m);
proto::TerrainDeformationMsg from_dds(const msg::TerrainDeformation& m);

msg::CollisionEvent to_dds(const proto::CollisionEventMsg& m);
proto::CollisionEventMsg from_dds(const msg::CollisionEvent& m);

}  // namespace syndds::dds
