#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <functional>
#include <optional>
#include <stdexcept>
#include <thread>
#include <vector>

#include "fusion/geometry/similarity2d.h"
#include "fusion/grid/grid_geometry.h"

namespace wm::fusion {

/// A registration that cannot run: no plan edges, no occupied cell, bounds that make no sense.
class RegistrationError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// One drawn edge, in the drawing's own frame (units as drawn).
struct DrawnEdge {
  Eigen::Vector2d p0, p1;
};

/// What the robots have seen: occupancy probabilities over a raster (row-major from the lower-left cell, NaN =
/// never observed), and optionally points on observed line elements [m, world frame].
struct ObservedMap {
  GridGeometry geometry;
  std::vector<float> probability;
  std::vector<Eigen::Vector2d> element_points;
};

struct RegistrationOptions {
  /// The search's centre: the placement now. The placement's translation (x, y) changes by at most
  /// `max_translation_m` in each coordinate, its angle by at most `max_rotation_rad` either way.
  Similarity2D initial;
  double max_translation_m = 10.0;
  double max_rotation_rad = 3.14159265358979323846;
  /// Scales tried: [scale_min, scale_max] in steps that move the farthest drawn point by one search cell; or, when
  /// `scale_candidates` is not empty, exactly those (e.g. the unit factors m, cm, mm, in, ft), each refined.
  double scale_min = 1.0, scale_max = 1.0;
  std::vector<double> scale_candidates;
  /// Refine the scale by least squares too (always when a range or candidates are searched).
  bool refine_scale = false;
  /// Cell of the search's finest level [m] (the grid's own cell when that is coarser). Angles step by
  /// cell / (distance of the farthest drawn point from the centroid): Olson's rule, one cell at the rim.
  double search_cell_m = 0.1;
  /// Rotations from the peaks of the direction histograms (a few candidates) instead of every angle in the bound;
  /// every angle is searched anyway when the histograms show no clear peak.
  bool rotations_from_directions = true;
  /// At most this many points sampled along the drawing for the search (spacing grows for big plans).
  std::size_t max_samples = 3000;
  /// Cells with P above this are occupied (the map-quality threshold).
  double occupied_probability = 0.65;
  /// The runner-up is the best hypothesis at least this far from the best (in translation of the centroid, or in
  /// rotation); the answer is ambiguous when its score reaches `ambiguity_ratio` of the best's.
  double separation_m = 1.0;
  double separation_rad = 0.1745;
  double ambiguity_ratio = 0.9;
  /// The search's score a placement must exceed to be searched for. That score is the mean likelihood-field value
  /// over the points sampled along the drawing, points outside the observed area counting 0: about the share of
  /// the whole drawing on occupied cells (score × coverage below). Windows whose bound does not exceed it are
  /// dropped with all they hold, so a drawing that fits nowhere is answered once no window can reach it: best is
  /// then the initial placement with score 0.
  double min_search_score = 0;
  /// Threads the search runs on, the calling one among them (at most 256). The placement found is the same for any
  /// number: ties between equal scores are broken by a fixed order, not by which thread found one first.
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  /// Wall-clock bound of the whole search; past it the best found so far is answered with timed_out set.
  std::chrono::milliseconds time_budget{10000};
  /// Called now and then with the share of the search done (0..1); returning false cancels the search.
  std::function<bool(double)> progress;
};

/// One placement hypothesis. `score`: the share of the drawing's length, within the observed area, that lies
/// on occupied cells (within one cell); `coverage`: the share of the drawing's length in the observed area.
struct PlacementHypothesis {
  Similarity2D placement;
  double score = 0;
  double coverage = 0;
};

struct RegistrationResult {
  PlacementHypothesis best;
  std::optional<PlacementHypothesis> runner_up;  // none when nothing reached 0.7 of the best's search score
  bool ambiguous = false;
  /// Covariance of (x [m], y [m], θ [rad], scale) from the refinement's residuals, cells taken as independent
  /// (so a lower bound); scale's row and column are zero when the scale was held.
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  double rms_m = 0;                // of the refinement's residuals
  std::size_t matched_points = 0;  // cells and element points the refinement used
  bool timed_out = false;
  bool cancelled = false;
  std::size_t hypotheses_scored = 0;  // search nodes scored
  double search_score = 0;            // the search's score of the best leaf; 0 when none exceeded min_search_score
  double seconds = 0;
};

/// Places a drawing on what the robots have seen: a correlative search over (x, y, θ[, scale]) of points sampled
/// along the drawn edges against a likelihood field of the occupied cells (Olson 2009), by branch and bound over
/// a max-pooled pyramid of that field (Hess et al. 2016), then a Gauss-Newton refinement of the drawn edges
/// against the occupied cells and element points near them (point to line, Huber-weighted).
/// @throw RegistrationError for no edge, no occupied cell, non-finite or non-positive bounds, a scale range that
///        would take more than 256 steps, a min_search_score outside [0, 1], or a number of threads outside [1, 256].
RegistrationResult register_plan(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                 const RegistrationOptions& options);

/// Scores a placement as register_plan does (score and coverage at the raster's own cell).
PlacementHypothesis score_placement(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                    const Similarity2D& placement, double occupied_probability = 0.65);

/// A drawing point and where it is in the world.
struct PointPair {
  Eigen::Vector2d drawn, world;
};

struct PairsPlacement {
  Similarity2D placement;
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();  // (x, y, θ, scale) as in RegistrationResult
  double rms_m = 0;                                      // world distance of the pairs after placing
};

/// The least-squares similarity (Umeyama 1991) that takes the drawn points onto the world points; the scale is
/// held at 1 unless `with_scale`. The covariance takes each world point as known to the larger of
/// `point_sigma_m` and the residuals' spread.
/// @throw RegistrationError for fewer than two pairs, a non-finite coordinate, or points that coincide (drawn or
///        world), which leave the rotation undetermined.
PairsPlacement place_from_pairs(const std::vector<PointPair>& pairs, bool with_scale, double point_sigma_m = 0.05);

}  // namespace wm::fusion
