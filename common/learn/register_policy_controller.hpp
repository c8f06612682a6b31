#pragma once
// The one entry point a program needs to run learned-policy controllers, without libtorch's
// headers (they cost about 25 s of compile per translation unit).

namespace syndds::learn {

/// Lets this process's agent factory build `controller: {type: policy}` members
/// (syndds_policy_controller, syndds_sim and syndds_group call it at start; the other programs
/// do not link libtorch). Defined in policy_controller.cpp.
void register_policy_controller();

}  // namespace syndds::learn
