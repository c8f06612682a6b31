// syndds_policy_controller: a learned policy driving one vehicle (`controller: {type: policy}`,
// docs/learning.md), as a barrier member. A program of its own so that only the members that
// run a policy load libtorch (about 90 MB and 0.3 s of CPU at start per process).
#include "common/member_main.hpp"
#include "learn/register_policy_controller.hpp"

int main(int argc, char** argv) {
  syndds::learn::register_policy_controller();
  std::string vehicle;
  return syndds::service::member_main(
      "policy_controller", "syndds policy controller: a learned policy drives one vehicle", argc,
      argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
      },
      [&](const syndds::scenario::Scenario&) {
        return syndds::scenario::controller_member(vehicle);
      });
}
