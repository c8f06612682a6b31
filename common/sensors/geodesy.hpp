#pragma once
// Geodetic conversions between the scenario's local ENU frame (x east, y north, z up, metres,
// origin at a geodetic point) and WGS84 latitude / longitude / altitude.
//
// Three models:
//  - wgs84: exact chain ENU -> ECEF -> geodetic on the WGS84 ellipsoid (a 6378137 m,
//    f 1/298.257223563); the local frame is the tangent plane at the origin (altitude
//    included: a point on the plane rises d^2 / 2R above the ellipsoid).
//  - wgs84_flat: first-order small-area form with the ellipsoid's radii of curvature at the
//    origin on the ellipsoid surface (meridian M, prime vertical N):
//    lat = lat0 + y / M, lon = lon0 + x / (N cos lat0), alt = alt0 + z. It ignores the origin
//    altitude (relative error h / R: 4e-5 at 260 m) and the curvature of the plane; this is
//    the "WGS84 tangent plane" number of docs/sources.md.
//  - sphere: Chrono::Sensor's approximation on a sphere of radius 6371000 m:
//    lat = lat0 + y / R, lon = lon0 + x / (R cos lat), alt = alt0 + z (cosine of the new
//    latitude, as Chrono does).
#include <string_view>

#include "core/math.hpp"

namespace syndds::sensors {

struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double alt_m = 0.0;
};

enum class GeodeticModel { wgs84, wgs84_flat, sphere };
/// "wgs84" | "wgs84_flat" | "sphere"; throws std::invalid_argument otherwise.
GeodeticModel parse_geodetic_model(std::string_view name);
std::string_view to_string(GeodeticModel model);

inline constexpr double kWgs84A = 6378137.0;
inline constexpr double kWgs84F = 1.0 / 298.257223563;
inline constexpr double kChronoEarthRadius = 6371000.0;

/// Chrono's demo origin (Madison, WI): the default scenario origin.
inline constexpr Geodetic kDefaultOrigin{43.070, -89.400, 260.0};

Vec3 geodetic_to_ecef(const Geodetic& g);
/// Iterative inverse (converges to well below a micrometre for |alt| < 1e6 m).
Geodetic ecef_to_geodetic(const Vec3& ecef);

/// Local tangent plane (ENU) at an origin on the WGS84 ellipsoid.
class LocalTangentPlane {
 public:
  explicit LocalTangentPlane(const Geodetic& origin);
  const Geodetic& origin() const { return origin_; }
  Vec3 enu_to_ecef(const Vec3& enu) const;
  Vec3 ecef_to_enu(const Vec3& ecef) const;
  Geodetic enu_to_geodetic(const Vec3& enu) const { return ecef_to_geodetic(enu_to_ecef(enu)); }
  Vec3 geodetic_to_enu(const Geodetic& g) const { return ecef_to_enu(geodetic_to_ecef(g)); }

 private:
  Geodetic origin_;
  Vec3 origin_ecef_;
  Eigen::Matrix3d enu_to_ecef_rot_;  // columns: east, north, up in ECEF
};

/// First-order form on the WGS84 radii of curvature at the origin (see above).
Geodetic flat_enu_to_geodetic(const Geodetic& origin, const Vec3& enu);
Vec3 flat_geodetic_to_enu(const Geodetic& origin, const Geodetic& g);

/// Chrono's spherical approximation.
Geodetic sphere_enu_to_geodetic(const Geodetic& origin, const Vec3& enu);
Vec3 sphere_geodetic_to_enu(const Geodetic& origin, const Geodetic& g);

/// Either model behind one interface (what the GPS uses).
class GeodeticConverter {
 public:
  GeodeticConverter(const Geodetic& origin, GeodeticModel model) : model_(model), plane_(origin) {}
  GeodeticModel model() const { return model_; }
  const Geodetic& origin() const { return plane_.origin(); }
  Geodetic to_geodetic(const Vec3& enu) const {
    switch (model_) {
      case GeodeticModel::wgs84:
        return plane_.enu_to_geodetic(enu);
      case GeodeticModel::wgs84_flat:
        return flat_enu_to_geodetic(plane_.origin(), enu);
      case GeodeticModel::sphere:
        break;
    }
    return sphere_enu_to_geodetic(plane_.origin(), enu);
  }
  Vec3 to_enu(const Geodetic& g) const {
    switch (model_) {
      case GeodeticModel::wgs84:
        return plane_.geodetic_to_enu(g);
      case GeodeticModel::wgs84_flat:
        return flat_geodetic_to_enu(plane_.origin(), g);
      case GeodeticModel::sphere:
        break;
    }
    return sphere_geodetic_to_enu(plane_.origin(), g);
  }

 private:
  GeodeticModel model_;
  LocalTangentPlane plane_;
};

}  // namespace syndds::sensors
