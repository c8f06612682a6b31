#include "protocol/messages.hpp"

#include <array>
#include <cmath>
#include <map>
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

namespace {
// TopicTraits' names indexed by the enum's value (kAllDataTopics lists the enum in order):
// every manifest entry of every grant is named through these, so a lookup is one index or one
// pass.
template <std::size_t... I>
constexpr std::array<std::string_view, sizeof...(I)> topic_names(std::index_sequence<I...>) {
  static_assert(((static_cast<std::size_t>(kAllDataTopics[I]) == I) && ...));
  return {std::string_view(TopicTraits<kAllDataTopics[I]>::name)...};
}
constexpr auto kTopicNames = topic_names(std::make_index_sequence<std::size(kAllDataTopics)>{});
}  // namespace

std::string_view to_string(Topic topic) {
  const auto i = static_cast<std::size_t>(topic);
  return i < std::size(kTopicNames) ? kTopicNames[i] : std::string_view("unknown");
}

bool topic_from_string(std::string_view name, Topic& topic) {
  for (std::size_t i = 0; i < std::size(kTopicNames); ++i) {
    if (kTopicNames[i] == name) {
      topic = kAllDataTopics[i];
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

std::string config_file_differences(const std::vector<std::string>& mine,
                                    const std::vector<std::string>& theirs) {
  if (mine.empty() || theirs.empty()) return "";
  auto split = [](const std::vector<std::string>& lines) {
    std::map<std::string, std::string> out;  // role -> hash
    for (const auto& line : lines) {
      const auto space = line.rfind(' ');
      if (space == std::string::npos) continue;
      out[line.substr(0, space)] = line.substr(space + 1);
    }
    return out;
  };
  const auto a = split(mine), b = split(theirs);
  std::string out;
  auto add = [&](const std::string& text) { out += (out.empty() ? "" : "; ") + text; };
  for (const auto& [role, hash] : a) {
    const auto it = b.find(role);
    if (it == b.end()) {
      add(role + " (only here)");
    } else if (it->second != hash) {
      add(role + " (" + hash + " here, " + it->second + " there)");
    }
  }
  for (const auto& [role, hash] : b) {
    if (!a.contains(role)) add(role + " (only there)");
  }
  return out;
}

}  // namespace syndds::proto
