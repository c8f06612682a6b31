#pragma once
// How the kernel schedules this process's threads. syndds members are many small processes that
// wake each other every frame (a grant to every member, a sample to every reader): under the
// default policy each wake-up may preempt the thread that sent it, so a coordinator fanning a
// grant out to 66 members was preempted about once per reader it woke. SCHED_BATCH keeps the
// CPU share of the default policy but a woken batch thread does not preempt the running one:
// the sender finishes its fan-out, and the wake-ups run after it (docs/performance.md, "Where
// the wake-ups are").
#include <string>

namespace syndds {

/// Applies "batch" (SCHED_BATCH) or "normal" (SCHED_OTHER) to the calling thread; threads it
/// creates afterwards inherit it, so call it before creating any. Throws ConfigError naming
/// `option` for another value. Returns an empty string, or why the kernel refused (e.g. a
/// sandbox that filters the system call): a scheduling hint is not worth failing a run for.
std::string set_cpu_policy(const std::string& policy, const std::string& option = "--cpu-policy");
/// The calling thread's policy: "batch", "normal" or "other".
std::string cpu_policy();

}  // namespace syndds
