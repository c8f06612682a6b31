#pragma once
// What a policy file says about how it was made (docs/learning.md, "Policy files"), kept in
// two places: inside the .pt file (Policy::metadata(), read by the controller that drives with
// it, so a run's fingerprint covers it) and beside it as <stem>.json, which programs without
// libtorch read (syndds_course and the scenario generators choose the followers' rig from it).
// Keys: `env` (environment name), `env_options` (KEY=VALUE, space separated, sorted),
// `sensors` (the rig a vehicle driven by the policy needs, config/sensors/<rig>.yaml),
// `network`, `seed`, `updates`, `interactions`, `init_from` (the earlier stage's file).
#include <map>
#include <optional>
#include <string>

namespace syndds::learn {

using PolicyMetadata = std::map<std::string, std::string>;

/// <dir>/<stem>.json for <dir>/<stem>.pt (any extension is replaced).
std::string policy_sidecar_path(const std::string& policy_file);

/// Writes `metadata` as a JSON object of strings (to a .tmp file, then renamed); throws
/// std::runtime_error if it cannot.
void write_policy_sidecar(const std::string& policy_file, const PolicyMetadata& metadata);

/// The sidecar of `policy_file`, if there is one; throws std::runtime_error naming the file if
/// it is not a JSON object of strings.
std::optional<PolicyMetadata> read_policy_sidecar(const std::string& policy_file);

}  // namespace syndds::learn
