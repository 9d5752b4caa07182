#pragma once

#include <Eigen/Core>

namespace wm::apriori {

/// Where the world frame sits on the Earth: the WGS 84 position of its origin (0, 0) and the compass bearing of
/// its +x axis. The frame is right-handed with z up, so +y points 90° counter-clockwise of +x: heading 90 means
/// +x east and +y north; heading 0 means +x north and +y west. 2-D: the origin lies on the ellipsoid (height 0).
struct Georeference {
  double latitude_deg = 0.0;   // WGS 84 geodetic latitude of the origin [deg], |φ| <= 89.9
  double longitude_deg = 0.0;  // WGS 84 longitude of the origin [deg], in [-180, 180]
  double heading_deg = 90.0;   // bearing of world +x, clockwise from true north [deg], in [-360, 360]
};

/// Checks the ranges documented on Georeference. The poles are excluded because there east and north (and so
/// the heading) are undefined.
/// @throw std::invalid_argument naming the field, e.g. "latitude_deg: expected a finite number in [-89.9, 89.9]".
void validate(const Georeference& georeference);

/// A WGS 84 position [deg] in GeoJSON's (RFC 7946) order.
struct LonLat {
  double longitude_deg = 0.0;  // in (-180, 180]
  double latitude_deg = 0.0;   // in [-90, 90]
};

/// Converts between the world frame's local metres and WGS 84 longitude/latitude. The world frame is taken to be
/// the local tangent plane (ENU) at the georeference's origin, rotated by the heading: a point (x, y) is placed
/// on that plane, converted exactly to ECEF and then to geodetic coordinates on the WGS 84 ellipsoid, and its
/// ellipsoidal height (the plane rising above the ellipsoid: 8 cm at 1 km) is dropped. So a point's position
/// is the foot of the ellipsoid normal through it, and lengths along the plane are kept to 1e-5 m at 1 km.
/// to_local() is the exact inverse (not the ENU of the ellipsoid point), so a round trip returns the input to
/// rounding.
/// Invariant: built from a valid Georeference.
class GeoreferenceTransform {
 public:
  /// @throw std::invalid_argument as validate().
  explicit GeoreferenceTransform(const Georeference& georeference);

  const Georeference& georeference() const { return georeference_; }

  /// The WGS 84 position of world point xy [m].
  /// @throw std::invalid_argument for a non-finite xy.
  LonLat to_lon_lat(const Eigen::Vector2d& xy_m) const;

  /// The world point [m] whose to_lon_lat() is p.
  /// @throw std::invalid_argument for a non-finite p or a latitude outside [-90, 90];
  ///        std::out_of_range when p is a quarter of the Earth or more away from the origin, where the ellipsoid
  ///        normal through p no longer meets the tangent plane.
  Eigen::Vector2d to_local(const LonLat& p) const;

 private:
  Georeference georeference_;
  Eigen::Vector3d origin_ecef_m_;  // the origin on the ellipsoid [m]
  Eigen::Vector3d x_axis_ecef_;    // unit vectors of world +x, +y and up, in ECEF
  Eigen::Vector3d y_axis_ecef_;
  Eigen::Vector3d up_ecef_;
};

}  // namespace wm::apriori
