#pragma once
// The viewer's DDS side: a participant of the run's domain and partition that only reads, never
// announces itself and never writes, so the coordinator does not know it exists and nothing
// in the run can wait for it. Vehicle states, soil deformations, collision events, camera images,
// lidar clouds and radar scans are read best effort (QoS profile viewer_reader: a missed sample
// is not shown, the next replaces it); announcements and the run's end reliably (they are rare).
#include <memory>
#include <vector>

#include "dds/participant.hpp"
#include "scenario/scenario.hpp"
#include "viewer/live_state.hpp"
#include "viewer/viewer_server.hpp"

namespace syndds::viewer {

class ViewerFeed {
 public:
  ViewerFeed(const dds::DdsOptions& options, const scenario::Scenario& scenario, LiveState& live,
             SensorStore& sensors);
  ~ViewerFeed();
  ViewerFeed(const ViewerFeed&) = delete;
  ViewerFeed& operator=(const ViewerFeed&) = delete;

 private:
  std::unique_ptr<dds::Participant> participant_;
  std::vector<std::shared_ptr<void>> readers_;
};

}  // namespace syndds::viewer
