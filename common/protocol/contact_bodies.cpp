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

namespace {

// What the test needs of a body, computed once per body.
struct Reach {
  Rect2 rect;
  double speed = 0.0;
  double bound = 0.0;  // radius of the circle about the rectangle's centre that holds it
};

Reach reach_of(const VehicleBodyMsg& b) {
  Reach r;
  r.rect = footprint_rect(b);
  r.speed = travel_speed(b);
  r.bound = std::hypot(r.rect.half_length, r.rect.half_width);
  return r;
}

bool reach_each_other(const Reach& a, const Reach& b, double frame_s) {
  const double margin = kBaseMarginM + 2.0 * frame_s * (a.speed + b.speed);
  // The circles first (a cheap rejection), then the rectangles.
  if ((a.rect.centre - b.rect.centre).norm() > a.bound + b.bound + margin) return false;
  return rects_within(a.rect, b.rect, margin);
}

}  // namespace

bool within_reach(const VehicleBodyMsg& a, const VehicleBodyMsg& b, double frame_s) {
  return reach_each_other(reach_of(a), reach_of(b), frame_s);
}

std::vector<VehicleBodyMsg> select_contact_bodies(std::vector<VehicleBodyMsg> bodies,
                                                  double frame_s) {
  std::vector<Reach> reach;
  reach.reserve(bodies.size());
  for (const auto& b : bodies) reach.push_back(reach_of(b));
  std::vector<char> keep(bodies.size(), 0);
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    for (std::size_t j = i + 1; j < bodies.size(); ++j) {
      if ((keep[i] && keep[j]) || !reach_each_other(reach[i], reach[j], frame_s)) continue;
      keep[i] = keep[j] = 1;
    }
  }
  std::vector<VehicleBodyMsg> out;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    if (keep[i]) out.push_back(std::move(bodies[i]));
  }
  // Only the few selected are sorted (most frames: none).
  std::stable_sort(out.begin(), out.end(), [](const VehicleBodyMsg& a, const VehicleBodyMsg& b) {
    return a.vehicle_id < b.vehicle_id;
  });
  out.erase(std::unique(out.begin(), out.end(),
                        [](const VehicleBodyMsg& a, const VehicleBodyMsg& b) {
                          return a.vehicle_id == b.vehicle_id;
                        }),
            out.end());
  return out;
}

}  // namespace syndds::proto
