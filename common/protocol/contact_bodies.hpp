#pragma once
// Which vehicles' collision states the barrier passes on (docs/vehicle-contact.md): the broad
// phase of vehicle-vehicle contact, a pure function of the bodies reported for frame k-1, so
// every process layout (distributed, grouped, one process) hands every vehicle the same ones.
#include <vector>

#include "core/rect2.hpp"
#include "protocol/messages.hpp"

namespace syndds::proto {

/// The body's footprint rectangle in the ground plane.
Rect2 footprint_rect(const VehicleBodyMsg& body);

/// True if `a` and `b` may touch within the next frame of `frame_s` seconds: their footprints
/// come within a margin of 0.5 m plus what both can travel in two frames (speed of the
/// reference point plus the angular speed times the footprint's half diagonal).
bool within_reach(const VehicleBodyMsg& a, const VehicleBodyMsg& b, double frame_s);

/// The bodies of vehicles within reach of at least one other, sorted by vehicle_id (a vehicle
/// reported twice keeps the body that came first).
std::vector<VehicleBodyMsg> select_contact_bodies(std::vector<VehicleBodyMsg> bodies,
                                                  double frame_s);

}  // namespace syndds::proto
