#include "core/cpu_policy.hpp"

#include <sched.h>

#include <cerrno>
#include <cstring>

#include "core/error.hpp"

namespace syndds {

std::string set_cpu_policy(const std::string& policy, const std::string& option) {
  int kind = 0;
  if (policy == "batch") {
    kind = SCHED_BATCH;
  } else if (policy == "normal") {
    kind = SCHED_OTHER;
  } else {
    throw ConfigError(option + " '" + policy + "': expected batch or normal");
  }
  sched_param param{};
  param.sched_priority = 0;
  if (sched_setscheduler(0, kind, &param) != 0) {
    return "could not set the CPU policy '" + policy + "': " + std::strerror(errno);
  }
  return {};
}

std::string cpu_policy() {
  switch (sched_getscheduler(0)) {
    case SCHED_BATCH: return "batch";
    case SCHED_OTHER: return "normal";
    default: return "other";
  }
}

}  // namespace syndds
