// syndds_sensor: renders one vehicle's cameras, lidars and radars (Embree) from the synced world.
#include "common/member_main.hpp"

int main(int argc, char** argv) {
  std::string vehicle;
  std::string output = "runs/latest";
  return syndds::service::member_main(
      "sensor", "syndds sensor: renders one vehicle's cameras, lidars and radars from the synced world",
      argc, argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
        app.add_option("--output", output, "Run directory (saved frames go to OUTPUT/sensors)")
            ->capture_default_str();
      },
      [&](const syndds::scenario::Scenario&) { return syndds::scenario::sensor_member(vehicle); },
      &output);
}
