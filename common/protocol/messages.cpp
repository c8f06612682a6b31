#include "protocol/messages.hpp"

#include <cmath>
#include <string>

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
  std::string_view name = "unknown";
  for_each_topic([&](auto t) {
    if (t.value == topic) name = TopicTraits<decltype(t)::value>::name;
  });
  return name;
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

std::string validate_command(const DriverCommandMsg& cmd) {
  auto check = [](const char* name, double v, double lo, double hi) -> std::string {
    if (!std::isfinite(v)) return std::string(name) + " is not a finite number";
    if (v < lo || v > hi) {
      return std::string(name) + " = " + std::to_string(v) + " is outside [" +
             std::to_string(lo) + ", " + std::to_string(hi) + "]";
    }
    return "";
  };
  for (const auto& err : {check("steering", cmd.steering, -1, 1),
                          check("throttle", cmd.throttle, 0, 1),
                          check("braking", cmd.braking, 0, 1)}) {
    if (!err.empty()) return err;
  }
  return "";
}

std::string_view to_string(RunStatus status) {
  return status == RunStatus::completed ? "completed" : "aborted";
}

}  // namespace syndds::proto
