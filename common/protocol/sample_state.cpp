#include "protocol/sample_state.hpp"

namespace syndds::proto {

void save_samples(core::StateWriter& w, const FrameSamples& samples) {
  w.begin("frame_samples", 2);
  auto& s = const_cast<FrameSamples&>(samples);  // message_io reads it only, for a writer
  for_each_topic([&](auto t) {
    constexpr Topic T = decltype(t)::value;
    w.io(std::string(TopicTraits<T>::name));
    message_io(w, s.list<T>());
  });
  message_io(w, s.contact_bodies);  // since version 2
  w.end();
}

FrameSamples load_samples(core::StateReader& r) {
  FrameSamples samples;
  const std::uint32_t version = r.begin("frame_samples", 2, 1);
  for_each_topic([&](auto t) {
    constexpr Topic T = decltype(t)::value;
    const auto name = r.get<std::string>();
    if (name != TopicTraits<T>::name) {
      r.fail("expected the samples of topic '" + std::string(TopicTraits<T>::name) + "', found '" +
             name + "' (written by a build with other topics)");
    }
    message_io(r, samples.list<T>());
  });
  if (version >= 2) message_io(r, samples.contact_bodies);
  r.end();
  return samples;
}

}  // namespace syndds::proto
