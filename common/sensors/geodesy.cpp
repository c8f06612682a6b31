#include "sensors/geodesy.hpp"

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace syndds::sensors {
namespace {
constexpr double kE2 = kWgs84F * (2.0 - kWgs84F);  // first eccentricity squared
}

GeodeticModel parse_geodetic_model(std::string_view name) {
  if (name == "wgs84") return GeodeticModel::wgs84;
  if (name == "wgs84_flat") return GeodeticModel::wgs84_flat;
  if (name == "sphere") return GeodeticModel::sphere;
  throw std::invalid_argument("unknown geodetic model '" + std::string(name) +
                              "' (wgs84 | wgs84_flat | sphere)");
}

std::string_view to_string(GeodeticModel model) {
  switch (model) {
    case GeodeticModel::wgs84:
      return "wgs84";
    case GeodeticModel::wgs84_flat:
      return "wgs84_flat";
    case GeodeticModel::sphere:
      break;
  }
  return "sphere";
}

namespace {
// Meridian (M) and prime-vertical (N) radii of curvature at a latitude, on the ellipsoid.
std::pair<double, double> curvature_radii(double lat_rad) {
  const double s = std::sin(lat_rad);
  const double w = 1.0 - kE2 * s * s;
  return {kWgs84A * (1.0 - kE2) / (w * std::sqrt(w)), kWgs84A / std::sqrt(w)};
}
}  // namespace

Geodetic flat_enu_to_geodetic(const Geodetic& origin, const Vec3& enu) {
  const double lat0 = deg_to_rad(origin.lat_deg);
  const auto [m, n] = curvature_radii(lat0);
  return {origin.lat_deg + rad_to_deg(enu.y() / m),
          origin.lon_deg + rad_to_deg(enu.x() / (n * std::cos(lat0))), origin.alt_m + enu.z()};
}

Vec3 flat_geodetic_to_enu(const Geodetic& origin, const Geodetic& g) {
  const double lat0 = deg_to_rad(origin.lat_deg);
  const auto [m, n] = curvature_radii(lat0);
  return {deg_to_rad(g.lon_deg - origin.lon_deg) * n * std::cos(lat0),
          deg_to_rad(g.lat_deg - origin.lat_deg) * m, g.alt_m - origin.alt_m};
}

Vec3 geodetic_to_ecef(const Geodetic& g) {
  const double lat = deg_to_rad(g.lat_deg);
  const double lon = deg_to_rad(g.lon_deg);
  const double s = std::sin(lat);
  const double c = std::cos(lat);
  const double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);  // prime vertical radius
  return {(n + g.alt_m) * c * std::cos(lon), (n + g.alt_m) * c * std::sin(lon),
          (n * (1.0 - kE2) + g.alt_m) * s};
}

Geodetic ecef_to_geodetic(const Vec3& ecef) {
  const double x = ecef.x(), y = ecef.y(), z = ecef.z();
  const double p = std::hypot(x, y);
  const double lon = std::atan2(y, x);
  // Fixed-point iteration on latitude (converges fast away from the poles; p == 0 handled).
  double lat = std::atan2(z, p * (1.0 - kE2));
  double alt = 0.0;
  for (int i = 0; i < 10; ++i) {
    const double s = std::sin(lat);
    const double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
    if (p > 1e-9) {
      alt = p / std::cos(lat) - n;
    } else {
      alt = std::abs(z) - n * (1.0 - kE2);
    }
    const double next = std::atan2(z, p * (1.0 - kE2 * n / (n + alt)));
    const bool done = std::abs(next - lat) < 1e-15;
    lat = next;
    if (done) break;
  }
  {
    const double s = std::sin(lat);
    const double n = kWgs84A / std::sqrt(1.0 - kE2 * s * s);
    alt = p > 1e-9 ? p / std::cos(lat) - n : std::abs(z) - n * (1.0 - kE2);
  }
  return {rad_to_deg(lat), rad_to_deg(lon), alt};
}

LocalTangentPlane::LocalTangentPlane(const Geodetic& origin)
    : origin_(origin), origin_ecef_(geodetic_to_ecef(origin)) {
  const double lat = deg_to_rad(origin.lat_deg);
  const double lon = deg_to_rad(origin.lon_deg);
  const double sl = std::sin(lat), cl = std::cos(lat);
  const double so = std::sin(lon), co = std::cos(lon);
  enu_to_ecef_rot_.col(0) = Vec3(-so, co, 0.0);
  enu_to_ecef_rot_.col(1) = Vec3(-sl * co, -sl * so, cl);
  enu_to_ecef_rot_.col(2) = Vec3(cl * co, cl * so, sl);
}

Vec3 LocalTangentPlane::enu_to_ecef(const Vec3& enu) const {
  return origin_ecef_ + enu_to_ecef_rot_ * enu;
}

Vec3 LocalTangentPlane::ecef_to_enu(const Vec3& ecef) const {
  return enu_to_ecef_rot_.transpose() * (ecef - origin_ecef_);
}

Geodetic sphere_enu_to_geodetic(const Geodetic& origin, const Vec3& enu) {
  Geodetic g;
  g.lat_deg = origin.lat_deg + rad_to_deg(enu.y() / kChronoEarthRadius);
  // Chrono divides by the cosine of the new latitude.
  g.lon_deg =
      origin.lon_deg + rad_to_deg(enu.x() / (kChronoEarthRadius * std::cos(deg_to_rad(g.lat_deg))));
  g.alt_m = origin.alt_m + enu.z();
  return g;
}

Vec3 sphere_geodetic_to_enu(const Geodetic& origin, const Geodetic& g) {
  const double y = deg_to_rad(g.lat_deg - origin.lat_deg) * kChronoEarthRadius;
  const double x =
      deg_to_rad(g.lon_deg - origin.lon_deg) * kChronoEarthRadius * std::cos(deg_to_rad(g.lat_deg));
  return {x, y, g.alt_m - origin.alt_m};
}

}  // namespace syndds::sensors
