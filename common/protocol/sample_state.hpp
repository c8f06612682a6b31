#pragma once
// Messages and frame samples in checkpoint state (core/state_io.hpp): every field of a message,
// in the order of its SYNDDS_FIELDS list, exactly. A member's checkpoint holds the samples it
// will step its next frame with, so a resumed member needs nothing from the network to start.
#include <type_traits>
#include <vector>

#include "core/state_io.hpp"
#include "protocol/agent.hpp"
#include "protocol/fields.hpp"

namespace syndds::proto {

namespace detail {
/// A list whose elements message_io handles itself (messages or poses).
template <typename T>
struct IsMessageList : std::false_type {};
template <typename T>
struct IsMessageList<std::vector<T>>
    : std::bool_constant<HasFields<T> || std::is_same_v<T, Pose>> {};
}  // namespace detail

/// Reads (StateReader) or writes (StateWriter) one value of a message: nested messages field by
/// field, poses, lists of either, and everything StateWriter::io knows.
template <typename Archive, typename T>
void message_io(Archive& a, T& v) {
  if constexpr (HasFields<T>) {
    for_each_field<T>([&](const char*, auto member, auto) { message_io(a, v.*member); });
  } else if constexpr (std::is_same_v<T, Pose>) {
    a.io(v.position);
    a.io(v.orientation);
  } else if constexpr (detail::IsMessageList<T>::value) {
    std::uint64_t n = v.size();
    a.io(n);
    if constexpr (std::is_same_v<Archive, core::StateReader>) v.resize(static_cast<std::size_t>(n));
    for (auto& x : v) message_io(a, x);
  } else {
    a.io(v);
  }
}

/// Every sample of every topic, in list order (section "frame_samples").
void save_samples(core::StateWriter& w, const FrameSamples& samples);
FrameSamples load_samples(core::StateReader& r);

}  // namespace syndds::proto
