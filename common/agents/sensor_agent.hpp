#pragma once
// The sensor member of one vehicle ("sensor/<id>"): keeps an Embree scene of the whole world
// (terrain with every vehicle's ruts, obstacles, every vehicle at its synced pose) and renders
// the vehicle's cameras, lidars and radars. In frame k it sees the states and deformations stamped
// k-1 (the world at t_{k-1}), renders it, and publishes what became available, stamped k.
// A vehicle lost under on_member_loss: continue leaves the scene in the frame it is reported.
#include <functional>
#include <map>
#include <memory>

#include "protocol/agent.hpp"
#include "record/run_files.hpp"
#include "scenario/scenario.hpp"
#include "scm/scm_terrain.hpp"
#include "sensors/image_io.hpp"
#include "sensors/rig.hpp"

namespace syndds::agents {

struct SensorAgentOptions {
  std::string output_dir;  // where saved frames / videos go (scenario decides whether to save)
  bool resume = false;     // continue the frame index of a checkpointed run (load_state)
  /// Commit the scene (rebuild its acceleration structures: most of a frame's cost when
  /// little is rendered) only in frames where a sensor may render, not in every frame. The
  /// images are the same either way; the scene() of a frame without a render is then stale
  /// (false: committed in every frame).
  bool commit_only_to_render = true;
};

class SensorAgent final : public proto::Agent {
 public:
  SensorAgent(const scenario::Scenario& scenario, const scenario::VehicleConfig& vehicle,
              SensorAgentOptions options);
  ~SensorAgent() override;

  const std::string& member_id() const override { return member_id_; }
  std::string vehicle_key() const override { return vehicle_id_; }
  proto::MemberKind kind() const override { return proto::MemberKind::sensor; }
  std::vector<proto::Subscription> subscriptions() const override;
  std::vector<proto::Topic> publications() const override;
  void step(const proto::FrameContext& ctx, const proto::FrameSamples& inputs,
            proto::FrameSamples& outputs) override;
  void finish(const proto::RunEnd& end, const proto::FrameSamples& final_inputs) override;
  /// Checkpoints: the sensors, the soil copy, the scene's vehicles and their poses, the frame
  /// index, the videos (each cut back to its frames of the checkpoint on load).
  bool can_checkpoint() const override { return true; }
  void save_state(core::StateWriter& w) override;
  void load_state(core::StateReader& r) override;

  const sensors::Scene& scene() const { return *scene_; }
  std::uint64_t frames_rendered() const { return frames_rendered_; }
  /// Every camera of the rig makes only the frames `filter` wants (CameraSensor::FrameFilter;
  /// the ticks are this agent's frames).
  void set_camera_frame_filter(const sensors::CameraSensor::FrameFilter& filter);

 private:
  void update_world(const proto::FrameSamples& inputs);
  void remove_departed(const std::vector<std::string>& departed);
  void render_vertex(std::int32_t i, std::int32_t j, std::vector<sensors::HeightUpdate>& out) const;
  void save(const sensors::RenderedBatch& batch);
  // The videos of the checkpoint `r` reads (`count` of them), each cut back to it.
  void load_videos(core::StateReader& r, std::uint64_t count);
  // The video of camera `id` (`open`: a new file, or the file of a checkpointed run).
  std::unique_ptr<sensors::VideoWriter> open_video(const std::string& id, int width, int height,
                                                   sensors::VideoWriter::Open open) const;

  std::string vehicle_id_;
  std::string member_id_;
  bool deformable_ = false;
  scenario::VehicleSensorsConfig config_;
  SensorAgentOptions options_;
  std::unique_ptr<scm::ScmTerrain> soil_;  // a copy of the deformable terrain (merged exactly)
  std::unique_ptr<sensors::Scene> scene_;
  std::unique_ptr<sensors::VehicleSensors> sensors_;
  // Camera id -> its video, from the camera's first frame on.
  std::map<std::string, std::unique_ptr<sensors::VideoWriter>> videos_;
  std::unique_ptr<record::CsvFile> index_;  // frames.csv, when frames are saved
  std::uint64_t frames_rendered_ = 0;
  // What the scene shows of each vehicle (kept for checkpoints: a vehicle whose states stop
  // arriving stays where it was, moving as it was), absent once removed.
  struct VehicleView {
    Pose chassis;
    std::vector<Pose> wheels;
    Vec3 linear_velocity = Vec3::Zero();  // radars see these as Doppler
    Vec3 angular_velocity = Vec3::Zero();
  };
  std::map<std::string, VehicleView> poses_;
  std::function<void()> reset_terrain_;  // the scene's soil as it was at the start (SCM)
  bool stepped_ = false;
};

}  // namespace syndds::agents
