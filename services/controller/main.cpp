// syndds_controller: the built-in driver of one vehicle (path follower or convoy follower), as a
// barrier member; learned policies run in syndds_policy_controller.
#include "common/member_main.hpp"

int main(int argc, char** argv) {
  std::string vehicle;
  return syndds::service::member_main(
      "controller", "syndds controller: drives one vehicle (path follower or convoy follower)", argc, argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
      },
      [&](const syndds::scenario::Scenario&) {
        return syndds::scenario::controller_member(vehicle);
      });
}
