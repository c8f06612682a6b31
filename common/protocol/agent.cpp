#include "protocol/agent.hpp"

#include <algorithm>
#include <map>
#include <tuple>

namespace syndds::proto {
namespace {

template <typename T>
void sort_by_key_source(std::vector<T>& v) {
  std::stable_sort(v.begin(), v.end(), [](const T& a, const T& b) {
    return std::tie(a.vehicle_id, a.source) < std::tie(b.vehicle_id, b.source);
  });
}

template <typename T>
void count_into(std::map<std::tuple<Topic, std::string, std::string>, std::uint32_t>& counts,
                Topic topic, const std::vector<T>& v, const std::string& writer) {
  for (const auto& s : v) ++counts[{topic, s.vehicle_id, writer}];
}

template <typename T>
void filter_into(const std::vector<T>& in, std::vector<T>& out, Topic topic,
                 const std::vector<Subscription>& subs) {
  for (const auto& s : in) {
    for (const auto& sub : subs) {
      if (sub.matches(topic, s.vehicle_id)) {
        out.push_back(s);
        break;
      }
    }
  }
}

template <typename T>
void append_all(std::vector<T>& to, const std::vector<T>& from) {
  to.insert(to.end(), from.begin(), from.end());
}

}  // namespace

void FrameSamples::sort() {
  sort_by_key_source(vehicle_states);
  sort_by_key_source(driver_commands);
  sort_by_key_source(terrain_deformations);
  sort_by_key_source(collision_events);
}

Manifest FrameSamples::manifest(const std::string& writer) const {
  std::map<std::tuple<Topic, std::string, std::string>, std::uint32_t> counts;
  count_into(counts, Topic::vehicle_state, vehicle_states, writer);
  count_into(counts, Topic::driver_command, driver_commands, writer);
  count_into(counts, Topic::terrain_deformation, terrain_deformations, writer);
  count_into(counts, Topic::collision_event, collision_events, writer);
  Manifest out;
  out.reserve(counts.size());
  for (const auto& [k, n] : counts) {
    out.push_back(TopicCount{std::get<0>(k), std::get<1>(k), std::get<2>(k), n});
  }
  return out;
}

FrameSamples FrameSamples::filtered(const std::vector<Subscription>& subs) const {
  FrameSamples out;
  filter_into(vehicle_states, out.vehicle_states, Topic::vehicle_state, subs);
  filter_into(driver_commands, out.driver_commands, Topic::driver_command, subs);
  filter_into(terrain_deformations, out.terrain_deformations, Topic::terrain_deformation, subs);
  filter_into(collision_events, out.collision_events, Topic::collision_event, subs);
  return out;
}

void FrameSamples::append(const FrameSamples& other) {
  append_all(vehicle_states, other.vehicle_states);
  append_all(driver_commands, other.driver_commands);
  append_all(terrain_deformations, other.terrain_deformations);
  append_all(collision_events, other.collision_events);
}

}  // namespace syndds::proto
