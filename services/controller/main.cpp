// syndds_controller: a path-following driver for one vehicle, as a barrier member.
#include "common/member_main.hpp"

int main(int argc, char** argv) {
  std::string vehicle;
  return syndds::service::member_main(
      "controller", "syndds controller: drives one vehicle along its scenario path", argc, argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
      },
      [&](const syndds::scenario::Scenario&) {
        return syndds::scenario::controller_member(vehicle);
      });
}
