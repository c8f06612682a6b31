#include "common/service_cli.hpp"
#include "scenario/scenario.hpp"

namespace syndds::service {

scenario::Scenario load_scenario(const CommonArgs& args) {
  auto s = load_scenario_config(args);
  scenario::place_obstacles(s);
  return s;
}

}  // namespace syndds::service
