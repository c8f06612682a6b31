#include "viewer/viewer_feed.hpp"

#include <chrono>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace syndds::viewer {
namespace {

constexpr const char* kViewerReader = "viewer_reader";
// Lidar points sent to a page, at most (every k-th point of a larger cloud).
constexpr std::size_t kMaxPoints = 20000;

double wall_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

template <typename Reader>
std::shared_ptr<void> keep(std::unique_ptr<Reader> r) {
  return std::shared_ptr<void>(std::move(r));
}

std::string jpeg_of(const proto::ImageMsg& m) {
  if (m.encoding != "rgb8" || m.width <= 0 || m.height <= 0 ||
      m.data.size() != static_cast<std::size_t>(m.width) * m.height * 3) {
    return {};
  }
  cv::Mat rgb(m.height, m.width, CV_8UC3, const_cast<std::uint8_t*>(m.data.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  std::vector<std::uint8_t> out;
  cv::imencode(".jpg", bgr, out, {cv::IMWRITE_JPEG_QUALITY, 80});
  return std::string(out.begin(), out.end());
}

}  // namespace

ViewerFeed::ViewerFeed(const dds::DdsOptions& options, const scenario::Scenario& scenario,
                       LiveState& live, SensorStore& sensors) {
  participant_ = std::make_unique<dds::Participant>(options);
  auto& p = *participant_;
  using Scope = dds::Participant::Scope;
  readers_.push_back(keep(p.make_reader<msg::VehicleState>(
      dds::topics::data(proto::Topic::vehicle_state), kViewerReader,
      [&live](msg::VehicleState&& s) {
        // The run's progress from the states (each vehicle publishes one per frame), not from
        // the grants: one more reader of the coordinator's grants would be one more delivery
        // on every frame's critical path.
        auto state = dds::from_dds(s);
        live.on_frame(state.frame, state.sim_time_s, wall_s());
        live.on_vehicle_state(state);
      },
      Scope::all_vehicles)));
  readers_.push_back(keep(p.make_reader<msg::CollisionEvent>(
      dds::topics::data(proto::Topic::collision_event), kViewerReader,
      [&live](msg::CollisionEvent&& e) { live.on_collision(dds::from_dds(e)); },
      Scope::all_vehicles)));
  if (scenario.terrain.deformable()) {
    readers_.push_back(keep(p.make_reader<msg::TerrainDeformation>(
        dds::topics::data(proto::Topic::terrain_deformation), kViewerReader,
        [&live](msg::TerrainDeformation&& d) { live.on_terrain(dds::from_dds(d).vertices); },
        Scope::all_vehicles)));
  }
  bool rendered = false;
  for (const auto& v : scenario.vehicles) rendered = rendered || v.has_rendered_sensors();
  if (rendered) {
    readers_.push_back(keep(p.make_reader<msg::Image>(
        dds::topics::data(proto::Topic::image), kViewerReader,
        [&sensors](msg::Image&& raw) {
          const auto m = dds::from_dds(raw);
          std::string jpeg = jpeg_of(m);
          if (!jpeg.empty()) {
            sensors.set_image(m.vehicle_id, {m.stamp.sensor_id, m.frame, std::move(jpeg), 0});
          }
        },
        Scope::all_vehicles)));
    readers_.push_back(keep(p.make_reader<msg::PointCloud>(
        dds::topics::data(proto::Topic::point_cloud), kViewerReader,
        [&sensors](msg::PointCloud&& raw) {
          const auto m = dds::from_dds(raw);
          SensorStore::Points pts{m.stamp.sensor_id, m.frame, {}, 0};
          const std::size_t stride = m.points.size() / kMaxPoints + 1;
          const Eigen::Matrix3d r = m.pose.orientation.toRotationMatrix();
          for (std::size_t k = 0; k < m.points.size(); k += stride) {
            const auto& q = m.points[k];
            if (!(q.range > 0)) continue;  // no return
            const Vec3 w = m.pose.position + r * Vec3(q.x, q.y, q.z);
            pts.xyz.insert(pts.xyz.end(), {static_cast<float>(w.x()), static_cast<float>(w.y()),
                                           static_cast<float>(w.z())});
          }
          sensors.set_points(m.vehicle_id, std::move(pts));
        },
        Scope::all_vehicles)));
  }
  bool radars = false;
  for (const auto& v : scenario.vehicles) {
    radars = radars || (v.sensors && !v.sensors->rig.radars.empty());
  }
  if (radars) {
    // Each radar's newest scan; the page draws its detections (docs/viewer.md, "Radar").
    readers_.push_back(keep(p.make_reader<msg::RadarScan>(
        dds::topics::data(proto::Topic::radar), kViewerReader,
        [&live](msg::RadarScan&& r) { live.on_radar(dds::from_dds(r)); }, Scope::all_vehicles)));
  }
  readers_.push_back(keep(p.make_reader<msg::MemberAnnounce>(
      dds::topics::kMemberAnnounce, dds::profiles::kProtocolReader,
      [&live](msg::MemberAnnounce&& a) { live.on_member(dds::from_dds(a), wall_s()); })));
  readers_.push_back(keep(p.make_reader<msg::RunControl>(
      dds::topics::kRunControl, dds::profiles::kProtocolReader,
      [&live](msg::RunControl&& c) { live.on_run_end(dds::from_dds(c)); })));
}

ViewerFeed::~ViewerFeed() {
  readers_.clear();  // before the participant they belong to
  participant_.reset();
}

}  // namespace syndds::viewer
