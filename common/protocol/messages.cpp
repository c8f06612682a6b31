#include "protocol/messages.hpp"

namespace syndds::proto {

std::string_view to_string(MemberKind kind) {
  switch (kind) {
    case MemberKind::vehicle: return "vehicle";
    case MemberKind::controller: return "controller";
    case MemberKind::recorder: return "recorder";
    case MemberKind::sensor: return "sensor";
    case MemberKind::external: return "external";
    case MemberKind::coordinator: return "coordinator";
  }
  return "unknown";
}

std::string_view to_string(Topic topic) {
  switch (topic) {
    case Topic::vehicle_state: return "vehicle_state";
    case Topic::driver_command: return "driver_command";
    case Topic::terrain_deformation: return "terrain_deformation";
    case Topic::collision_event: return "collision_event";
  }
  return "unknown";
}

bool topic_from_string(std::string_view name, Topic& topic) {
  for (Topic t : kAllDataTopics) {
    if (to_string(t) == name) {
      topic = t;
      return true;
    }
  }
  return false;
}

std::string_view to_string(RunStatus status) {
  return status == RunStatus::completed ? "completed" : "aborted";
}

}  // namespace syndds::proto
