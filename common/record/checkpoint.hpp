#pragma once
// Checkpoint files of a run directory (docs/checkpoints.md):
//
//   RUN_DIR/checkpoints/frame_000000500/<member>.state   one per member, written by its process
//   RUN_DIR/checkpoints/frame_000000500/complete.yaml    written once every member's file is
//
// A checkpoint "of frame K" holds every member's state after it stepped frame K and the samples
// stamped K it will step frame K+1 with; a run resumed from it starts with frame K+1. Only a
// checkpoint with complete.yaml is ever resumed from. Each state file is framed with its length
// and checksum (core::frame_state) and written atomically, so a member killed while writing
// leaves the previous file or none, never a partial one; every file and directory is synced
// (directories too, after the rename that publishes a file), so a checkpoint declared complete
// survives a power loss.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "core/build_identity.hpp"
#include "protocol/agent.hpp"
#include "protocol/local_runner.hpp"

namespace syndds::record {

/// RUN_DIR/checkpoints/frame_<K, nine digits>.
std::filesystem::path checkpoint_dir(const std::filesystem::path& run_dir, std::int64_t frame);
/// The state file name of a member ("controller/a" -> "controller.a.state").
std::string member_state_file(const std::string& member_id);

/// Writes `agent`'s state after `frame` and `next_inputs` (the samples stamped `frame` it
/// subscribes to) to the checkpoint of `frame`, with the build that wrote it (`build_id`:
/// core/build_identity.hpp). Returns the bytes written. Throws WriteError.
std::uint64_t write_member_checkpoint(const std::filesystem::path& run_dir, std::int64_t frame,
                                      std::uint64_t fingerprint, proto::Agent& agent,
                                      const proto::FrameSamples& next_inputs,
                                      const std::string& build_id = build_identity());
/// Restores `agent` (built from the same scenario, not stepped yet) from the checkpoint of
/// `frame`; returns the samples it steps frame + 1 with. Throws core::StateError naming the file,
/// also for a checkpoint of another build (other physics or protocol sources), naming both.
proto::FrameSamples read_member_checkpoint(const std::filesystem::path& run_dir,
                                           std::int64_t frame, std::uint64_t fingerprint,
                                           proto::Agent& agent);

struct CheckpointMember {
  std::string member_id;
  std::uint64_t bytes = 0;
  double write_s = 0.0;  // wall time to save and write (single process only; else 0)
};
struct CheckpointInfo {
  std::int64_t frame = 0;
  double sim_time_s = 0.0;
  std::uint64_t fingerprint = 0;
  std::vector<CheckpointMember> members;
};
/// Declares the checkpoint of info.frame complete (every member's file is written).
void mark_checkpoint_complete(const std::filesystem::path& run_dir, const CheckpointInfo& info);
/// The complete checkpoint of `frame`; throws core::StateError if it is missing or incomplete.
CheckpointInfo read_checkpoint_info(const std::filesystem::path& run_dir, std::int64_t frame);
/// The frame of the latest complete checkpoint in `run_dir`, if any.
std::optional<std::int64_t> latest_complete_checkpoint(const std::filesystem::path& run_dir);
/// The frames of every complete checkpoint in `run_dir`, oldest first.
std::vector<std::int64_t> complete_checkpoints(const std::filesystem::path& run_dir);

/// Deletes what a run no longer needs once the checkpoint of `completed` is complete: of the
/// checkpoints before it, the complete ones beyond the `keep_last` newest (`completed` counts as
/// one) and every incomplete one. Checkpoints after `completed` are never touched: a member may
/// be writing one, and after a resume or a rollback they are rewritten when the run reaches
/// them. `completed` itself, the checkpoint a rollback or a resume starts from, is always kept.
/// Returns the frames deleted, oldest first; throws WriteError naming a directory that cannot
/// be deleted (the ones before it are gone).
std::vector<std::int64_t> prune_checkpoints(const std::filesystem::path& run_dir,
                                            std::int64_t completed, std::int64_t keep_last);

using proto::checkpoint_due;

/// One process (syndds_sim): writes every agent's checkpoint of the stepper's last completed
/// frame, then declares it complete.
CheckpointInfo write_local_checkpoint(const std::filesystem::path& run_dir,
                                      proto::FrameStepper& stepper, std::uint64_t fingerprint,
                                      double heartbeat_s);
/// Restores every agent of a fresh `stepper` from the complete checkpoint of `frame` and
/// resumes the stepper after it.
void resume_local(const std::filesystem::path& run_dir, std::int64_t frame,
                  std::uint64_t fingerprint, proto::FrameStepper& stepper);

}  // namespace syndds::record
