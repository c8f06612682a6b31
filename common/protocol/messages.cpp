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

std::string_view to_string(RunStatus status) {
  return status == RunStatus::completed ? "completed" : "aborted";
}

}  // namespace syndds::proto
