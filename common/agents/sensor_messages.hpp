#pragma once
// Sensor samples of common/sensors as wire messages (stamped with a frame and a writer).
#include "protocol/agent.hpp"
#include "sensors/rig.hpp"

namespace syndds::agents {

/// Appends the interoceptive samples of `batch` to `out`, stamped (frame, source).
void append_messages(const sensors::InteroceptiveBatch& batch, const std::string& vehicle_id,
                     const std::string& source, std::int64_t frame, proto::FrameSamples& out);
/// Appends camera frames, lidar and radar scans of `batch` to `out`, stamped (frame, source).
void append_messages(const sensors::RenderedBatch& batch, const std::string& vehicle_id,
                     const std::string& source, std::int64_t frame, proto::FrameSamples& out);

}  // namespace syndds::agents
