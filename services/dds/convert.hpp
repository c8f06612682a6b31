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

msg::TerrainSnapshot to_dds(const proto::TerrainSnapshotMsg& m);
proto::TerrainSnapshotMsg from_dds(const msg::TerrainSnapshot& m);

msg::CollisionEvent to_dds(const proto::CollisionEventMsg& m);
proto::CollisionEventMsg from_dds(const msg::CollisionEvent& m);

msg::GpsFix to_dds(const proto::GpsFixMsg& m);
proto::GpsFixMsg from_dds(const msg::GpsFix& m);
msg::Imu to_dds(const proto::ImuMsg& m);
proto::ImuMsg from_dds(const msg::Imu& m);
msg::Magnetometer to_dds(const proto::MagnetometerMsg& m);
proto::MagnetometerMsg from_dds(const msg::Magnetometer& m);
msg::WheelSpeeds to_dds(const proto::WheelSpeedsMsg& m);
proto::WheelSpeedsMsg from_dds(const msg::WheelSpeeds& m);
msg::Image to_dds(const proto::ImageMsg& m);
proto::ImageMsg from_dds(const msg::Image& m);
msg::PointCloud to_dds(const proto::PointCloudMsg& m);
proto::PointCloudMsg from_dds(const msg::PointCloud& m);
msg::V2VMessage to_dds(const proto::V2VMessageMsg& m);
proto::V2VMessageMsg from_dds(const msg::V2VMessage& m);
msg::VehicleEvent to_dds(const proto::VehicleEventMsg& m);
proto::VehicleEventMsg from_dds(const msg::VehicleEvent& m);

/// The generated type of each data topic.
template <proto::Topic T>
struct DdsType;
#define SYNDDS_DDS_TOPIC(TOPIC, TYPE) \
  template <>                         \
  struct DdsType<proto::Topic::TOPIC> { using type = msg::TYPE; };
SYNDDS_DDS_TOPIC(vehicle_state, VehicleState)
SYNDDS_DDS_TOPIC(driver_command, DriverCommand)
SYNDDS_DDS_TOPIC(terrain_deformation, TerrainDeformation)
SYNDDS_DDS_TOPIC(terrain_snapshot, TerrainSnapshot)
SYNDDS_DDS_TOPIC(collision_event, CollisionEvent)
SYNDDS_DDS_TOPIC(gps_fix, GpsFix)
SYNDDS_DDS_TOPIC(imu, Imu)
SYNDDS_DDS_TOPIC(magnetometer, Magnetometer)
SYNDDS_DDS_TOPIC(wheel_speeds, WheelSpeeds)
SYNDDS_DDS_TOPIC(image, Image)
SYNDDS_DDS_TOPIC(point_cloud, PointCloud)
SYNDDS_DDS_TOPIC(v2v_message, V2VMessage)
SYNDDS_DDS_TOPIC(vehicle_event, VehicleEvent)
#undef SYNDDS_DDS_TOPIC

}  // namespace syndds::dds
