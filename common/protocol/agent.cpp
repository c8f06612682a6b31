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

}  // namespace

std::vector<std::string> subscribed_keys(const std::vector<Subscription>& subs, Topic topic) {
  std::vector<std::string> keys;
  for (const auto& s : subs) {
    if (s.topic != topic) continue;
    if (s.key.empty()) return {};
    keys.push_back(s.key);
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

void FrameSamples::sort() {
  for_each_topic([&](auto t) { sort_by_key_source(list<decltype(t)::value>()); });
  std::stable_sort(contact_bodies.begin(), contact_bodies.end(),
                   [](const VehicleBodyMsg& a, const VehicleBodyMsg& b) {
                     return a.vehicle_id < b.vehicle_id;
                   });
}

Manifest FrameSamples::manifest(const std::string& writer) const {
  std::map<std::tuple<Topic, std::string, std::string>, std::uint32_t> counts;
  for_each_topic([&](auto t) { count_into(counts, t.value, list<decltype(t)::value>(), writer); });
  Manifest out;
  out.reserve(counts.size());
  for (const auto& [k, n] : counts) {
    out.push_back(TopicCount{std::get<0>(k), std::get<1>(k), std::get<2>(k), n});
  }
  return out;
}

FrameSamples FrameSamples::filtered(const std::vector<Subscription>& subs) const {
  FrameSamples out;
  for_each_topic([&](auto t) { filter_into(list<decltype(t)::value>(), out.list<decltype(t)::value>(), t.value, subs); });
  out.contact_bodies = contact_bodies;
  return out;
}

void FrameSamples::append(const FrameSamples& other) {
  for_each_topic([&](auto t) {
    auto& to = list<decltype(t)::value>();
    const auto& from = other.list<decltype(t)::value>();
    to.insert(to.end(), from.begin(), from.end());
  });
  contact_bodies.insert(contact_bodies.end(), other.contact_bodies.begin(),
                        other.contact_bodies.end());
}

}  // namespace syndds::proto
