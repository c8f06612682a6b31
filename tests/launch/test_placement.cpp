#include <gtest/gtest.h>

#include "common/run_plan.hpp"

namespace service = syndds::service;

namespace {

std::vector<service::PlannedProcess> processes(const std::vector<std::string>& names) {
  std::vector<service::PlannedProcess> out;
  for (const auto& n : names) out.push_back({n, {"/bin/true"}});
  return out;
}

}  // namespace

TEST(Placement, RunProcessesOnTheFirstHostAndAVehicleTogether) {
  const auto p = processes({"coordinator", "vehicle/a", "controller/a", "sensor/a", "vehicle/b",
                            "controller/b", "recorder"});
  const auto hosts = service::place_processes(p, {4, 4});
  // coordinator + recorder (2) on host 0; a (3) goes to host 1 (3/4 < 5/4); b (2) to host 0
  // (4/4 < 5/4).
  EXPECT_EQ(hosts, (std::vector<int>{0, 1, 1, 1, 0, 0, 0}));
}

TEST(Placement, SlotsWeighTheChoice) {
  const auto p = processes({"coordinator", "group/a", "group/b", "group/c", "recorder"});
  // Host 1 has three times the slots: it takes every group ((k+1)/6 < (2+1)/2).
  EXPECT_EQ(service::place_processes(p, {2, 6}), (std::vector<int>{0, 1, 1, 1, 0}));
  // One host: everything there.
  EXPECT_EQ(service::place_processes(p, {1}), (std::vector<int>{0, 0, 0, 0, 0}));
}

TEST(Placement, VehicleOfAProcess) {
  EXPECT_EQ(service::vehicle_of_process("controller/lead_1"), "lead_1");
  EXPECT_EQ(service::vehicle_of_process("group/a"), "a");
  EXPECT_EQ(service::vehicle_of_process("recorder"), "");
  EXPECT_EQ(service::vehicle_of_process("coordinator"), "");
}
