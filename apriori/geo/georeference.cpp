#include "apriori/geo/georeference.h"

#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>

namespace wm::apriori {
namespace {

// WGS 84 ellipsoid (NIMA TR8350.2): semi-major axis [m] and flattening; e² the first eccentricity squared,
// e'² the second.
constexpr double kA = 6378137.0;
constexpr double kF = 1.0 / 298.257223563;
constexpr double kB = kA * (1.0 - kF);
constexpr double kE2 = kF * (2.0 - kF);
constexpr double kEp2 = kE2 / (1.0 - kE2);

constexpr double kMaxAbsLatitudeDeg = 89.9;

double radians(double deg) { return deg * (std::numbers::pi / 180.0); }
double degrees(double rad) { return rad * (180.0 / std::numbers::pi); }

void check_range(const char* field, double value, double low, double high) {
  if (std::isfinite(value) && value >= low && value <= high) return;
  std::ostringstream message;
  message << field << ": expected a finite number in [" << low << ", " << high << "], got " << value;
  throw std::invalid_argument(message.str());
}

/// Outward unit normal of the ellipsoid at geodetic latitude φ, longitude λ [rad] (= the local "up").
Eigen::Vector3d ellipsoid_normal(double lat, double lon) {
  return {std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
}

/// ECEF [m] of the point at geodetic latitude, longitude [rad] on the ellipsoid (height 0).
Eigen::Vector3d geodetic_to_ecef(double lat, double lon) {
  const double s = std::sin(lat);
  const double n = kA / std::sqrt(1.0 - kE2 * s * s);  // prime-vertical radius of curvature [m]
  return {n * std::cos(lat) * std::cos(lon), n * std::cos(lat) * std::sin(lon), n * (1.0 - kE2) * s};
}

/// Geodetic longitude and latitude [deg] of ECEF point q [m], height dropped. Bowring's formula (Survey Review
/// 23(181), 1976) iterated on the parametric latitude: one step is already well under a millimetre near the
/// surface; the loop runs to convergence (1e-15 rad, 6 nm) so nothing rests on that bound. No division, so a
/// point on the polar axis still gives ±90°.
LonLat ecef_to_lon_lat(const Eigen::Vector3d& q) {
  const double p = std::hypot(q.x(), q.y());
  double beta = std::atan2(kA * q.z(), kB * p);  // parametric latitude, first guess for height 0
  double lat = 0.0;
  for (int i = 0; i < 10; ++i) {
    const double sb = std::sin(beta);
    const double cb = std::cos(beta);
    const double next = std::atan2(q.z() + kEp2 * kB * sb * sb * sb, p - kE2 * kA * cb * cb * cb);
    const bool converged = i > 0 && std::abs(next - lat) < 1e-15;
    lat = next;
    if (converged) break;
    beta = std::atan2((1.0 - kF) * std::sin(lat), std::cos(lat));
  }
  return {degrees(std::atan2(q.y(), q.x())), degrees(lat)};
}

}  // namespace

void validate(const Georeference& georeference) {
  check_range("latitude_deg", georeference.latitude_deg, -kMaxAbsLatitudeDeg, kMaxAbsLatitudeDeg);
  check_range("longitude_deg", georeference.longitude_deg, -180.0, 180.0);
  check_range("heading_deg", georeference.heading_deg, -360.0, 360.0);
}

GeoreferenceTransform::GeoreferenceTransform(const Georeference& georeference) : georeference_(georeference) {
  validate(georeference_);
  const double lat = radians(georeference_.latitude_deg);
  const double lon = radians(georeference_.longitude_deg);
  const double heading = radians(georeference_.heading_deg);
  origin_ecef_m_ = geodetic_to_ecef(lat, lon);
  // The ENU axes at the origin in ECEF; world +x is `heading` clockwise from north, +y 90° counter-clockwise of
  // +x (right-handed with z up).
  const Eigen::Vector3d east(-std::sin(lon), std::cos(lon), 0.0);
  const Eigen::Vector3d north(-std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat));
  up_ecef_ = ellipsoid_normal(lat, lon);
  x_axis_ecef_ = std::sin(heading) * east + std::cos(heading) * north;
  y_axis_ecef_ = -std::cos(heading) * east + std::sin(heading) * north;
}

LonLat GeoreferenceTransform::to_lon_lat(const Eigen::Vector2d& xy_m) const {
  if (!xy_m.allFinite()) throw std::invalid_argument("GeoreferenceTransform::to_lon_lat: non-finite point");
  return ecef_to_lon_lat(origin_ecef_m_ + xy_m.x() * x_axis_ecef_ + xy_m.y() * y_axis_ecef_);
}

Eigen::Vector2d GeoreferenceTransform::to_local(const LonLat& p) const {
  if (!std::isfinite(p.longitude_deg) || !std::isfinite(p.latitude_deg) || std::abs(p.latitude_deg) > 90.0)
    throw std::invalid_argument("GeoreferenceTransform::to_local: non-finite longitude or latitude out of range");
  const double lat = radians(p.latitude_deg);
  const double lon = radians(p.longitude_deg);
  // to_lon_lat() drops the height along the ellipsoid normal, so the inverse is where that normal through the
  // point on the ellipsoid meets the tangent plane: (q + t·n − o)·up = 0.
  const Eigen::Vector3d normal = ellipsoid_normal(lat, lon);
  const double cos_tilt = normal.dot(up_ecef_);
  if (!(cos_tilt > 0.0))
    throw std::out_of_range("GeoreferenceTransform::to_local: the point is a quarter of the Earth or more away");
  const Eigen::Vector3d from_origin = geodetic_to_ecef(lat, lon) - origin_ecef_m_;
  const Eigen::Vector3d on_plane = from_origin - (from_origin.dot(up_ecef_) / cos_tilt) * normal;
  return {on_plane.dot(x_axis_ecef_), on_plane.dot(y_axis_ecef_)};
}

}  // namespace wm::apriori
