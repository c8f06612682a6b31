#include <gtest/gtest.h>

#include <thread>

#include "vehicle/ode_vehicle.hpp"

using namespace syndds;

// Several ODE vehicles stepped from several threads at once (single-process runs, in-process
// DDS tests) must neither crash nor disturb each other: results equal a lone run.
TEST(OdeThreads, ConcurrentVehiclesMatchALoneVehicle) {
  const auto params = vehicle::load_vehicle_params(std::string(SYNDDS_TEST_CONFIG_DIR) +
                                                   "/vehicles/hmmwv.yaml");
  auto drive = [&](Vec3* out) {
    vehicle::OdeVehicleModel m(params, Pose{}, std::make_shared<terrain::FlatTerrain>());
    m.set_inputs({0.3, 0.6, 0.0});
    for (int i = 0; i < 1500; ++i) m.advance(0.002);
    *out = m.snapshot().pose.position;
  };
  Vec3 alone;
  drive(&alone);
  std::vector<Vec3> results(4);
  std::vector<std::thread> threads;
  for (auto& r : results) threads.emplace_back(drive, &r);
  for (auto& t : threads) t.join();
  for (const auto& r : results) EXPECT_EQ(r, alone);
}
