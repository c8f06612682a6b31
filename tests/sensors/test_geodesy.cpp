#include <gtest/gtest.h>

#include "sensors/geodesy.hpp"

using namespace syndds;
using namespace syndds::sensors;

// docs/sources.md: from (43.070 N, -89.400 E, 260 m), local (100, 100, 0).
TEST(Geodesy, SphereMatchesChronoOracle) {
  const Geodetic g = sphere_enu_to_geodetic(kDefaultOrigin, Vec3(100, 100, 0));
  EXPECT_NEAR(g.lat_deg, 43.070899322, 1e-8);
  EXPECT_NEAR(g.lon_deg, -89.398768911, 1e-8);
  EXPECT_DOUBLE_EQ(g.alt_m, 260.0);
}

// The oracle's "WGS84 tangent plane" is the first-order form on the ellipsoid radii at the origin.
TEST(Geodesy, Wgs84FlatMatchesOracle) {
  const Geodetic g = flat_enu_to_geodetic(kDefaultOrigin, Vec3(100, 100, 0));
  EXPECT_NEAR(g.lat_deg, 43.070900138, 1e-8);
  EXPECT_NEAR(g.lon_deg, -89.398772228, 1e-8);
  EXPECT_LT((flat_geodetic_to_enu(kDefaultOrigin, g) - Vec3(100, 100, 0)).norm(), 1e-9);
}

// The exact chain differs from the first-order oracle by the origin altitude (radius M + h
// instead of M: 260 / 6.36e6 of 9e-4 deg = 3.7e-8 deg) and second-order terms (< 2e-8 deg).
TEST(Geodesy, Wgs84ExactChainAgreesWithOracleUpToAltitudeTerm) {
  const LocalTangentPlane plane(kDefaultOrigin);
  const Geodetic g = plane.enu_to_geodetic(Vec3(100, 100, 0));
  EXPECT_NEAR(g.lat_deg, 43.070900138 - 8.99e-4 * 260.0 / 6.36e6, 1e-8);
  EXPECT_NEAR(g.lat_deg, 43.070900094, 1e-9);  // independent closed-form (Bowring) value
  EXPECT_NEAR(g.lon_deg, -89.398772260, 1e-9);
  EXPECT_NEAR(g.lon_deg, -89.398772228, 5e-8);
  // A point 141 m away on the tangent plane sits h = d^2 / (2 R) ~ 1.6 mm above the ellipsoid.
  EXPECT_NEAR(g.alt_m - 260.0, 141.42 * 141.42 / (2.0 * 6.37e6), 3e-4);
  // With the origin on the ellipsoid the latitude agrees with the oracle to 1e-8 deg.
  const Geodetic g0 = LocalTangentPlane({43.070, -89.400, 0.0}).enu_to_geodetic(Vec3(100, 100, 0));
  EXPECT_NEAR(g0.lat_deg, 43.070900138, 1e-8);
}

TEST(Geodesy, EcefOfKnownPoints) {
  // Equator / prime meridian at sea level: (a, 0, 0); the pole: (0, 0, b).
  const Vec3 e = geodetic_to_ecef({0.0, 0.0, 0.0});
  EXPECT_NEAR(e.x(), kWgs84A, 1e-6);
  EXPECT_NEAR(e.norm(), kWgs84A, 1e-6);
  const Vec3 p = geodetic_to_ecef({90.0, 0.0, 0.0});
  EXPECT_NEAR(p.z(), kWgs84A * (1.0 - kWgs84F), 1e-6);  // b = 6356752.314 m
  EXPECT_NEAR(p.z(), 6356752.314, 1e-3);
}

TEST(Geodesy, RoundTripsEnuEcefGeodetic) {
  for (const Geodetic& origin : {kDefaultOrigin, Geodetic{-33.9, 151.2, 40.0},
                                 Geodetic{78.2, 15.6, 0.0}, Geodetic{0.0, 0.0, -20.0}}) {
    const LocalTangentPlane plane(origin);
    for (const Vec3& enu :
         {Vec3(0, 0, 0), Vec3(100, 100, 0), Vec3(-2500, 1200, 35), Vec3(40000, -30000, 800)}) {
      const Geodetic g = plane.enu_to_geodetic(enu);
      const Vec3 back = plane.geodetic_to_enu(g);
      EXPECT_LT((back - enu).norm(), 1e-6) << enu.transpose();
      const Vec3 ecef = plane.enu_to_ecef(enu);
      const Geodetic g2 = ecef_to_geodetic(ecef);
      EXPECT_LT((geodetic_to_ecef(g2) - ecef).norm(), 1e-6);
    }
    const Geodetic o = plane.enu_to_geodetic(Vec3::Zero());
    EXPECT_NEAR(o.lat_deg, origin.lat_deg, 1e-11);
    EXPECT_NEAR(o.lon_deg, origin.lon_deg, 1e-11);
    EXPECT_NEAR(o.alt_m, origin.alt_m, 1e-6);
  }
}

TEST(Geodesy, SphereRoundTripAndModelsAgreeLocally) {
  const GeodeticConverter sphere(kDefaultOrigin, GeodeticModel::sphere);
  const GeodeticConverter wgs(kDefaultOrigin, GeodeticModel::wgs84);
  const Vec3 enu(350.0, -120.0, 4.0);
  EXPECT_LT((sphere.to_enu(sphere.to_geodetic(enu)) - enu).norm(), 1e-6);
  // The models differ by the ellipsoid's local radii (~0.3 %): tens of cm over 350 m.
  const Geodetic a = sphere.to_geodetic(enu);
  const Geodetic b = wgs.to_geodetic(enu);
  EXPECT_LT(std::abs(a.lat_deg - b.lat_deg) * 111000.0, 1.0);
  EXPECT_LT(std::abs(a.lon_deg - b.lon_deg) * 81000.0, 1.0);
  const GeodeticConverter flat(kDefaultOrigin, GeodeticModel::wgs84_flat);
  EXPECT_LT((flat.to_enu(flat.to_geodetic(enu)) - enu).norm(), 1e-6);
  EXPECT_EQ(parse_geodetic_model("wgs84_flat"), GeodeticModel::wgs84_flat);
  EXPECT_THROW(parse_geodetic_model("flat"), std::invalid_argument);
}
