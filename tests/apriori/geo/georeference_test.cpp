#include "apriori/geo/georeference.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace wm::apriori {
namespace {

/// gtest assertion that `text` contains `part` (the tests do not link gmock's matchers).
::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << part << "' not found in:\n" << text;
}

/// Distance [m] between two nearby WGS 84 positions, to compare results in metres rather than degrees (a local
/// spherical approximation, good to 1 % of the difference, which is all a tolerance needs).
double gap_m(const LonLat& a, const LonLat& b) {
  constexpr double kMetresPerDegree = 6371000.0 * std::numbers::pi / 180.0;
  const double dlon = std::remainder(a.longitude_deg - b.longitude_deg, 360.0);
  const double east = dlon * kMetresPerDegree * std::cos(a.latitude_deg * std::numbers::pi / 180.0);
  return std::hypot(east, (a.latitude_deg - b.latitude_deg) * kMetresPerDegree);
}

// Reference positions from PROJ 9.1 (Debian bookworm), an independent implementation of the same conversion,
// through GDAL 3.6.2's gdaltransform:
//   echo "E N 0" | gdaltransform -ct "+proj=pipeline +step +inv +proj=topocentric +ellps=WGS84 +lon_0=LON
//     +lat_0=LAT +h_0=0 +step +inv +proj=cart +ellps=WGS84 +step +proj=unitconvert +xy_in=rad +xy_out=deg"
// with (E, N) the point's east/north offset [m] from the origin (the heading rotation done by hand where it is not
// a multiple of 90°). gdaltransform prints 15 significant digits, about 1e-8 m.
struct Reference {
  Georeference origin;
  Eigen::Vector2d xy_m;
  LonLat expected;
};

const Reference kReferences[] = {
    // 1000 m east of 45° N 7° E. Cross-check of a different formula: the geodesic from the origin to this point
    // (SpatiaLite 5.0.1's ST_Distance(..., 1) and ST_Azimuth) is 999.999991834 m at azimuth 90.00000000002°:
    // the tangent plane is 8 µm longer than the ground over 1 km.
    {{45.0, 7.0, 90.0}, {1000.0, 0.0}, {7.01268281703984, 44.9999992957776}},
    // Heading 0: +x points north, so x = 1000 m is 1000 m north.
    {{45.0, 7.0, 0.0}, {1000.0, 0.0}, {7.0, 45.0089983191476}},
    // Southern and western hemispheres, heading 270 (+x west, +y south): E = -250 m, N = 730 m.
    {{-33.8568, -70.6, 270.0}, {250.0, -730.0}, {-70.6027013412261, -33.8502186353034}},
    // Crossing the antimeridian eastwards: the longitude wraps to -180 + ...; E = 2000 m, N = 500 m.
    {{64.1, 179.999, 90.0}, {2000.0, 500.0}, {-179.959973476091, 64.1044793744722}},
    // A heading that is not a multiple of 90°: E = -719.7905143298212 m, N = 73.02005190912541 m.
    {{52.52, 13.405, 37.5}, {-380.25, 615.5}, {13.3943958831094, 52.5206557244608}},
};

TEST(GeoreferenceTransformTest, MatchesProjOnKnownPoints) {
  for (const auto& r : kReferences) {
    SCOPED_TRACE(::testing::Message() << "origin " << r.origin.latitude_deg << ", " << r.origin.longitude_deg
                                      << " heading " << r.origin.heading_deg);
    const GeoreferenceTransform t(r.origin);
    EXPECT_LT(gap_m(t.to_lon_lat(r.xy_m), r.expected), 1e-6);  // 1 µm; a spherical Earth is off by metres
    EXPECT_LT((t.to_local(r.expected) - r.xy_m).norm(), 1e-6);
  }
}

TEST(GeoreferenceTransformTest, OriginMapsToTheGeoreferencePosition) {
  const GeoreferenceTransform t({-12.25, 101.5, 200.0});
  const LonLat o = t.to_lon_lat({0.0, 0.0});
  EXPECT_NEAR(o.longitude_deg, 101.5, 1e-12);
  EXPECT_NEAR(o.latitude_deg, -12.25, 1e-12);
}

TEST(GeoreferenceTransformTest, RoundTripIsWithinAMicrometreAtOneKilometre) {
  for (const double heading : {-300.0, 0.0, 17.0, 90.0, 233.5}) {
    for (const double lat : {-89.9, -51.0, 0.0, 45.0, 89.9}) {
      const GeoreferenceTransform t({lat, -179.9995, heading});
      for (int k = 0; k < 12; ++k) {
        const double angle = k * std::numbers::pi / 6.0;
        const Eigen::Vector2d xy(1000.0 * std::cos(angle), 1000.0 * std::sin(angle));
        const Eigen::Vector2d back = t.to_local(t.to_lon_lat(xy));
        EXPECT_LT((back - xy).norm(), 1e-6) << "lat " << lat << " heading " << heading << " k " << k;
      }
    }
  }
}

TEST(GeoreferenceTransformTest, HeadingRotatesTheFrameClockwiseFromNorth) {
  const Georeference base{48.0, 11.0, 0.0};
  const GeoreferenceTransform north_up(base);
  // Heading 0: +x north (same longitude, higher latitude), +y west (same side as smaller longitude).
  const LonLat ahead = north_up.to_lon_lat({100.0, 0.0});
  EXPECT_NEAR(ahead.longitude_deg, 11.0, 1e-12);
  EXPECT_GT(ahead.latitude_deg, 48.0);
  const LonLat left = north_up.to_lon_lat({0.0, 100.0});
  EXPECT_LT(left.longitude_deg, 11.0);
  // Heading 90 is heading 0 turned a quarter clockwise: its +x (east) is heading 0's -y, its +y (north) heading 0's
  // +x, so its point (x, y) is heading 0's (y, -x).
  const GeoreferenceTransform east_up({48.0, 11.0, 90.0});
  const Eigen::Vector2d p(123.0, -45.0);
  EXPECT_LT(gap_m(east_up.to_lon_lat(p), north_up.to_lon_lat({p.y(), -p.x()})), 1e-9);
  // -270 and 90 are the same bearing; so are 360 and 0.
  EXPECT_LT(gap_m(GeoreferenceTransform({48.0, 11.0, -270.0}).to_lon_lat(p), east_up.to_lon_lat(p)), 1e-9);
  EXPECT_LT(gap_m(GeoreferenceTransform({48.0, 11.0, 360.0}).to_lon_lat(p), north_up.to_lon_lat(p)), 1e-9);
  // Heading 30: +x is 30° east of north, so 1 km along x is 500 m east and 866 m north of the origin.
  const GeoreferenceTransform h30({48.0, 11.0, 30.0});
  const GeoreferenceTransform enu({48.0, 11.0, 90.0});
  EXPECT_LT(gap_m(h30.to_lon_lat({1000.0, 0.0}), enu.to_lon_lat({500.0, 1000.0 * std::sqrt(3.0) / 2.0})), 1e-9);
}

TEST(GeoreferenceTest, ValidateNamesTheBadField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const auto message = [](const Georeference& g) {
    try {
      validate(g);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_TRUE(contains(message({nan, 0, 0}), "latitude_deg: expected a finite number in [-89.9, 89.9]"));
  EXPECT_TRUE(contains(message({89.95, 0, 0}), "latitude_deg"));
  EXPECT_TRUE(contains(message({-90.0, 0, 0}), "latitude_deg"));
  EXPECT_TRUE(contains(message({0, 180.0001, 0}), "longitude_deg: expected a finite number in [-180, 180]"));
  EXPECT_TRUE(contains(message({0, -inf, 0}), "longitude_deg"));
  EXPECT_TRUE(contains(message({0, 0, 360.5}), "heading_deg: expected a finite number in [-360, 360]"));
  EXPECT_TRUE(contains(message({0, 0, nan}), "heading_deg"));
  EXPECT_THROW(GeoreferenceTransform({0, 0, inf}), std::invalid_argument);
  // The bounds themselves are valid.
  EXPECT_NO_THROW(validate({89.9, -180.0, -360.0}));
  EXPECT_NO_THROW(validate({-89.9, 180.0, 360.0}));
}

TEST(GeoreferenceTransformTest, BadPointsAreRejected) {
  const GeoreferenceTransform t({45.0, 7.0, 90.0});
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(t.to_lon_lat({nan, 0.0}), std::invalid_argument);
  EXPECT_THROW(t.to_lon_lat({0.0, std::numeric_limits<double>::infinity()}), std::invalid_argument);
  EXPECT_THROW(t.to_local({nan, 45.0}), std::invalid_argument);
  EXPECT_THROW(t.to_local({7.0, 90.5}), std::invalid_argument);
  EXPECT_THROW(t.to_local({-173.0, -45.0}), std::out_of_range);  // the antipode
}

}  // namespace
}  // namespace wm::apriori
