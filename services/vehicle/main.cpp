// syndds_vehicle: one vehicle's dynamics as a barrier member.
#include "common/member_main.hpp"

int main(int argc, char** argv) {
  std::string vehicle;
  return syndds::service::member_main(
      "vehicle", "syndds vehicle: one vehicle's dynamics, publishing its state every frame", argc,
      argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
      },
      [&](const syndds::scenario::Scenario&) { return syndds::scenario::vehicle_member(vehicle); });
}
