#include "protocol/contact_bodies.hpp"

#include <algorithm>
#include <cmath>

namespace syndds::proto {
namespace {

constexpr double kBaseMarginM = 0.5;

double travel_speed(const VehicleBodyMsg& b) {
  const double half_diagonal = std::hypot(std::abs(b.footprint_offset_m) + b.footprint_half_length_m,
                                          b.footprint_half_width_m);
  return b.linear_velocity.norm() + b.angular_velocity.norm() * half_diagonal;
}

}  // namespace

Rect2 footprint_rect(const VehicleBodyMsg& body) {
  const double yaw = yaw_of(body.pose.orientation);
  Rect2 r;
  r.yaw = yaw;
  r.centre = Vec2(body.pose.position.x(), body.pose.position.y()) +
             body.footprint_offset_m * Vec2(std::cos(yaw), std::sin(yaw));
  r.half_length = body.footprint_half_length_m;
  r.half_width = body.footprint_half_width_m;
  return r;
}

bool within_reach(const VehicleBodyMsg& a, const VehicleBodyMsg& b, double frame_s) {
  const double margin = kBaseMarginM + 2.0 * frame_s * (travel_speed(a) + travel_speed(b));
  return rects_within(footprint_rect(a), footprint_rect(b), margin);
}

std::vector<VehicleBodyMsg> select_contact_bodies(std::vector<VehicleBodyMsg> bodies,
                                                  double frame_s) {
  std::stable_sort(bodies.begin(), bodies.end(),
                   [](const VehicleBodyMsg& a, const VehicleBodyMsg& b) {
                     return a.vehicle_id < b.vehicle_id;
                   });
  bodies.erase(std::unique(bodies.begin(), bodies.end(),
                           [](const VehicleBodyMsg& a, const VehicleBodyMsg& b) {
                             return a.vehicle_id == b.vehicle_id;
                           }),
               bodies.end());
  std::vector<char> keep(bodies.size(), 0);
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    for (std::size_t j = i + 1; j < bodies.size(); ++j) {
      if ((keep[i] && keep[j]) || !within_reach(bodies[i], bodies[j], frame_s)) continue;
      keep[i] = keep[j] = 1;
    }
  }
  std::vector<VehicleBodyMsg> out;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    if (keep[i]) out.push_back(std::move(bodies[i]));
  }
  return out;
}

}  // namespace syndds::proto
