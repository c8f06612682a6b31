// syndds_controller: the driver of one vehicle (path follower, convoy follower or learned
// policy), as a barrier member.
#include "common/member_main.hpp"
#include "learn/policy_controller.hpp"

int main(int argc, char** argv) {
  syndds::learn::register_policy_controller();
  std::string vehicle;
  return syndds::service::member_main(
      "controller", "syndds controller: drives one vehicle (path follower, convoy follower or learned policy)", argc, argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
      },
      [&](const syndds::scenario::Scenario&) {
        return syndds::scenario::controller_member(vehicle);
      });
}
