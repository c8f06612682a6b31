#pragma once

#include <string>
#include <vector>

namespace syndds::launch {

/// Fast DDS's shared-memory ports of DDS domain `domain` (7400 + 250 domain and the 249 after
/// it) whose files in `dir` (/dev/shm) an earlier run left behind: a port file is stale when it
/// belongs to this user, no process maps it (every process using a port maps it, /proc/PID/maps)
/// and it was last written at least `min_age_s` ago (Fast DDS creates and maps a port in one
/// step; the age keeps a port being created by a run starting beside this one). Removes each
/// stale port's files (fastrtps_portP, its _el and _sl locks and its sem.fastrtps_portP_mutex)
/// and returns the ports removed, in increasing order.
///
/// Why: a participant that aborts while shutting down (a Fast DDS 2.9 assertion) keeps its
/// count on every port it wrote to, so none of the run's port files is removed; the next run
/// on the domain reopens them and some of its processes never receive from others (join or
/// frame-0 timeouts), as measured in docs/performance.md.
std::vector<int> remove_stale_shm_ports(const std::string& dir, int domain, double min_age_s = 1.0);

}  // namespace syndds::launch
