#include "dds/grant_hub.hpp"

#include "dds/convert.hpp"

namespace syndds::dds {

GrantHub::GrantHub(std::shared_ptr<Participant> participant)
    : participant_(std::move(participant)) {
  reader_ = participant_->make_reader<msg::FrameGrant>(
      topics::kFrameGrant, profiles::kProtocolReader, [this](msg::FrameGrant&& m) {
        proto::FrameGrantMsg grant;
        std::string error;
        try {
          grant = from_dds(m);
        } catch (const std::exception& e) {
          error = e.what();
        }
        std::lock_guard lock(mutex_);
        if (!error.empty()) {
          for (auto& [id, handlers] : members_) handlers.second(error);
          return;
        }
        const proto::Manifest manifest = std::move(grant.manifest);
        grant.manifest.clear();
        for (auto& [id, handlers] : members_) handlers.first(grant, manifest);
      });
}

GrantHub::~GrantHub() { reader_.reset(); }

int GrantHub::add(Sink on_grant, Failure on_malformed) {
  std::lock_guard lock(mutex_);
  members_.emplace(next_id_, std::make_pair(std::move(on_grant), std::move(on_malformed)));
  return next_id_++;
}

void GrantHub::remove(int id) {
  std::lock_guard lock(mutex_);
  members_.erase(id);
}

}  // namespace syndds::dds
