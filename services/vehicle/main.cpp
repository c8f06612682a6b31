// syndds_vehicle: one vehicle's dynamics as a barrier member.
#include "agents/vehicle_agent.hpp"
#include "common/member_main.hpp"
#include "core/error.hpp"

int main(int argc, char** argv) {
  std::string vehicle;
  std::string hash_log;
  return syndds::service::member_main(
      "vehicle", "syndds vehicle: one vehicle's dynamics, publishing its state every frame", argc,
      argv,
      [&](CLI::App& app) {
        app.add_option("--vehicle", vehicle, "Vehicle id from the scenario")->required();
        app.add_option("--debug-terrain-hash-log", hash_log,
                       "Write the deformable terrain's grid hash at every frame boundary here")
            ->group("Testing (fault injection; never needed in normal runs)");
      },
      [&](const syndds::scenario::Scenario&) { return syndds::scenario::vehicle_member(vehicle); },
      nullptr,
      [&](syndds::proto::Agent& agent) {
        if (hash_log.empty()) return;
        auto* v = dynamic_cast<syndds::agents::VehicleAgent*>(&agent);
        if (!v || !v->soil()) throw syndds::ConfigError("--debug-terrain-hash-log needs SCM terrain");
        v->log_terrain_hashes(hash_log);
      });
}
