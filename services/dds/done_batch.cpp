#include "dds/done_batch.hpp"

#include <spdlog/spdlog.h>

#include <stdexcept>

#include "dds/convert.hpp"

namespace syndds::dds {

DoneBatch::DoneBatch(std::shared_ptr<Participant> participant)
    : participant_(std::move(participant)),
      writer_(participant_->make_writer<msg::FrameDones>(topics::kFrameDones,
                                                         profiles::kProtocolWriter)),
      watcher_([this] { watch(); }) {}

DoneBatch::~DoneBatch() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    try {
      send_locked(gather_.overdue(1e300));
    } catch (const std::exception& e) {
      spdlog::warn("frame_dones: {}", e.what());
    }
  }
  cv_.notify_all();
  watcher_.join();
  writer_.reset();
}

double DoneBatch::now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
}

void DoneBatch::add(proto::FrameDoneMsg done) {
  std::lock_guard lock(mutex_);
  send_locked(gather_.add(std::move(done), now()));
  cv_.notify_all();  // a new deadline, or none
}

void DoneBatch::leave(const std::string& member) {
  std::lock_guard lock(mutex_);
  send_locked(gather_.leave(member));
  cv_.notify_all();
}

std::uint64_t DoneBatch::samples_written() const {
  std::lock_guard lock(mutex_);
  return written_;
}

void DoneBatch::send_locked(std::vector<proto::FrameDoneMsg> dones) {
  if (dones.empty()) return;
  proto::FrameDonesMsg batch;
  batch.dones = std::move(dones);
  if (!writer_->write(to_dds(batch))) throw std::runtime_error("DDS refused a frame_dones sample");
  ++written_;
}

void DoneBatch::watch() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    const auto deadline = gather_.deadline();
    if (!deadline) {
      cv_.wait(lock);
      continue;
    }
    const double wait_s = *deadline - now();
    if (wait_s > 0) {
      cv_.wait_for(lock, std::chrono::duration<double>(wait_s));
      continue;
    }
    const auto overdue = gather_.overdue(now());
    if (!overdue.empty()) {
      spdlog::debug("frame_dones: {} done(s) of frame {} sent without the process's other "
                    "members'", overdue.size(), overdue.front().frame);
    }
    try {
      send_locked(overdue);
    } catch (const std::exception& e) {
      spdlog::error("frame_dones: {}", e.what());
    }
  }
}

}  // namespace syndds::dds
