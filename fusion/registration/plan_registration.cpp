#include "fusion/registration/plan_registration.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <unordered_map>

namespace wm::fusion {
namespace {

constexpr double kPi = 3.14159265358979323846;
// Levels of the max-pooled pyramid above the finest: a root covers 2^7 = 128 search cells (Cartographer's
// default branch-and-bound depth).
constexpr int kLevels = 7;
constexpr std::size_t kMaxScaleSteps = 256;
// What one search may take on: (scale, angle) pairs, and root windows over all of them (32 bytes each in memory).
constexpr std::size_t kMaxRotations = 200000;
constexpr std::size_t kMaxRoots = 4000000;
// How far around a direction-histogram peak rotations are searched [rad]: the spread of the directions read from
// rasterised walls (±1.5° at 160° on GDC1) that the correlation's peak still carries.
constexpr double kPeakHalfWidth = 1.0 * kPi / 180;

bool finite(const Eigen::Vector2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

Eigen::Vector2d perp(const Eigen::Vector2d& v) { return {-v.y(), v.x()}; }

double total_length(const std::vector<DrawnEdge>& edges) {
  double length = 0;
  for (const auto& e : edges) length += (e.p1 - e.p0).norm();
  return length;
}

// `count` points spread evenly by length along the edges (each in the middle of its stretch), drawn frame.
std::vector<Eigen::Vector2d> sample_edges(const std::vector<DrawnEdge>& edges, std::size_t count) {
  std::vector<Eigen::Vector2d> samples;
  const double length = total_length(edges);
  if (length <= 0 || count == 0) return samples;
  const double step = length / static_cast<double>(count);
  samples.reserve(count + edges.size());
  double carry = 0.5 * step;  // distance from the start of the next edge to its first sample
  for (const auto& e : edges) {
    const double l = (e.p1 - e.p0).norm();
    for (double t = carry; t < l; t += step) samples.push_back(e.p0 + (e.p1 - e.p0) * (t / l));
    const double past = l - carry;
    carry = past < 0 ? -past : step - std::fmod(past, step);
    if (carry <= 0 || carry > step) carry = step;
  }
  return samples;
}

void validate(const std::vector<DrawnEdge>& edges, const ObservedMap& observed, const RegistrationOptions& o) {
  if (edges.empty()) throw RegistrationError("the plan has no edges to place");
  for (const auto& e : edges)
    if (!finite(e.p0) || !finite(e.p1)) throw RegistrationError("a plan edge has a non-finite coordinate");
  if (total_length(edges) <= 0) throw RegistrationError("the plan's edges have no length");
  const auto cells = static_cast<std::size_t>(observed.geometry.width() * observed.geometry.height());
  if (observed.probability.size() != cells) throw RegistrationError("the raster's values do not match its size");
  const auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!std::isfinite(o.max_translation_m) || o.max_translation_m < 0 || o.max_translation_m > 1000)
    throw RegistrationError("max_translation_m: expected a number in [0, 1000]");
  if (!std::isfinite(o.max_rotation_rad) || o.max_rotation_rad < 0)
    throw RegistrationError("max_rotation: expected a finite angle >= 0");
  if (!positive(o.scale_min) || !positive(o.scale_max) || o.scale_min > o.scale_max)
    throw RegistrationError("scale: expected 0 < min <= max");
  for (const double s : o.scale_candidates)
    if (!positive(s)) throw RegistrationError("scale candidates: expected positive numbers");
  if (!positive(o.search_cell_m)) throw RegistrationError("search_cell_m: expected a positive number");
  if (!std::isfinite(o.initial.x_m) || !std::isfinite(o.initial.y_m) || !std::isfinite(o.initial.theta_rad) ||
      !positive(o.initial.scale))
    throw RegistrationError("the initial placement is not finite");
}

// A raster with a margin of `pad` cells on every side, so that windows reaching past the observed area read zeros.
struct Field {
  std::int64_t width = 0, height = 0, pad = 0;
  std::vector<float> values;
  float at(std::int64_t x, std::int64_t y) const {  // x, y without the margin
    x += pad;
    y += pad;
    if (x < 0 || y < 0 || x >= width || y >= height) return 0.0f;
    return values[static_cast<std::size_t>(y * width + x)];
  }
};

// The likelihood field at the search cell and its max-pooled levels: level h at (x, y) holds the largest value of
// level 0 over [x, x + 2^h) × [y, y + 2^h), so a window's score there bounds every placement inside it.
struct Pyramid {
  Eigen::Vector2d origin_m;  // world position of the lower-left corner of search cell (0, 0)
  double cell_m = 0;
  std::vector<Field> levels;
};

Pyramid build_pyramid(const ObservedMap& observed, double search_cell_m, double occupied_probability) {
  const auto& g = observed.geometry;
  const auto k = std::max<std::int64_t>(1, std::llround(search_cell_m / g.resolution_m()));
  Pyramid pyramid;
  pyramid.origin_m = g.origin_m();
  pyramid.cell_m = g.resolution_m() * static_cast<double>(k);
  const std::int64_t w = (g.width() + k - 1) / k, h = (g.height() + k - 1) / k;
  const std::int64_t pad = (std::int64_t{1} << kLevels) + 4;
  Field base{w + 2 * pad, h + 2 * pad, pad, {}};
  base.values.assign(static_cast<std::size_t>(base.width * base.height), 0.0f);
  // A search cell is occupied when any cell of the raster in it is; the field falls off as exp(-d²/2σ²), σ = one
  // search cell, which tolerates the one-cell shift the angular step allows at the rim.
  constexpr int kRadius = 3;
  float kernel[2 * kRadius + 1][2 * kRadius + 1];
  for (int dy = -kRadius; dy <= kRadius; ++dy)
    for (int dx = -kRadius; dx <= kRadius; ++dx)
      kernel[dy + kRadius][dx + kRadius] = static_cast<float>(std::exp(-0.5 * (dx * dx + dy * dy)));
  std::vector<char> occupied(static_cast<std::size_t>(w * h), 0);
  for (std::int64_t y = 0; y < g.height(); ++y)
    for (std::int64_t x = 0; x < g.width(); ++x) {
      const float p = observed.probability[static_cast<std::size_t>(y * g.width() + x)];
      if (p > occupied_probability) occupied[static_cast<std::size_t>((y / k) * w + x / k)] = 1;
    }
  for (std::int64_t y = 0; y < h; ++y)
    for (std::int64_t x = 0; x < w; ++x) {
      if (!occupied[static_cast<std::size_t>(y * w + x)]) continue;
      for (int dy = -kRadius; dy <= kRadius; ++dy)
        for (int dx = -kRadius; dx <= kRadius; ++dx) {
          auto& v = base.values[static_cast<std::size_t>((y + dy + pad) * base.width + x + dx + pad)];
          v = std::max(v, kernel[dy + kRadius][dx + kRadius]);
        }
    }
  pyramid.levels.push_back(std::move(base));
  for (int level = 1; level <= kLevels; ++level) {
    const Field& below = pyramid.levels.back();
    const std::int64_t half = std::int64_t{1} << (level - 1);
    Field next{below.width, below.height, pad, std::vector<float>(below.values.size(), 0.0f)};
    for (std::int64_t y = 0; y < next.height; ++y)
      for (std::int64_t x = 0; x < next.width; ++x) {
        float m = below.values[static_cast<std::size_t>(y * below.width + x)];
        if (x + half < below.width) m = std::max(m, below.values[static_cast<std::size_t>(y * below.width + x + half)]);
        if (y + half < below.height) {
          m = std::max(m, below.values[static_cast<std::size_t>((y + half) * below.width + x)]);
          if (x + half < below.width)
            m = std::max(m, below.values[static_cast<std::size_t>((y + half) * below.width + x + half)]);
        }
        next.values[static_cast<std::size_t>(y * next.width + x)] = m;
      }
    pyramid.levels.push_back(std::move(next));
  }
  return pyramid;
}

// One (scale, angle) of the search with the translation window in search cells: [-window, window]².
struct Rotation {
  double scale = 1, theta = 0;
};

struct Candidate {
  std::size_t rotation = 0;
  std::int64_t ox = 0, oy = 0;
  float score = 0;
};

class Search {
 public:
  Search(const std::vector<Eigen::Vector2d>& samples, const Eigen::Vector2d& centroid_drawn,
         const Similarity2D& initial, const Pyramid& pyramid, std::vector<Rotation> rotations, std::int64_t window,
         const RegistrationOptions& options, std::chrono::steady_clock::time_point deadline)
      : samples_(samples),
        centroid_drawn_(centroid_drawn),
        initial_(initial),
        pyramid_(pyramid),
        rotations_(std::move(rotations)),
        window_(window),
        options_(options),
        deadline_(deadline) {}

  // The best leaf scoring above `floor`; leaves within the separation of `excluded` are passed over.
  std::optional<Candidate> run(float floor, const std::optional<Candidate>& excluded, double progress_from,
                               double progress_to) {
    excluded_ = excluded;
    best_.reset();
    best_score_ = floor;
    std::vector<Candidate> roots;
    const std::int64_t step = std::int64_t{1} << kLevels;
    std::vector<Eigen::Vector2i> points;
    for (std::size_t r = 0; r < rotations_.size(); ++r) {
      discretize(r, points);
      for (std::int64_t oy = -window_; oy <= window_; oy += step)
        for (std::int64_t ox = -window_; ox <= window_; ox += step)
          roots.push_back({r, ox, oy, score(points, ox, oy, kLevels)});
      // The clock is read after every rotation's roots (at most kMaxRoots in all, bounded before the search).
      if (timed_out_ || std::chrono::steady_clock::now() > deadline_) {
        timed_out_ = true;
        return best_;
      }
    }
    std::sort(roots.begin(), roots.end(), [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
    for (std::size_t i = 0; i < roots.size(); ++i) {
      if (roots[i].score <= best_score_) break;
      if (i % 64 == 0 && options_.progress &&
          !options_.progress(progress_from + (progress_to - progress_from) * static_cast<double>(i) /
                                                 static_cast<double>(roots.size()))) {
        cancelled_ = true;
        return best_;
      }
      discretize(roots[i].rotation, points);
      expand(roots[i], kLevels, points);
      if (stopped()) break;
    }
    return best_;
  }

  // The placement of a leaf: the drawing's centroid at its cell, turned and scaled by its rotation.
  Similarity2D placement(const Candidate& c) const {
    const auto& r = rotations_[c.rotation];
    const Eigen::Vector2d centroid = centroid_world(c);
    const Eigen::Vector2d t = centroid - r.scale * (Eigen::Rotation2Dd(r.theta) * centroid_drawn_);
    return {t.x(), t.y(), r.theta, r.scale};
  }

  float best_score() const { return best_score_; }
  std::size_t scored() const { return scored_; }
  bool timed_out() const { return timed_out_; }
  bool cancelled() const { return cancelled_; }

 private:
  // Where the window's centre puts the drawing's centroid: the initial placement's translation with this rotation's
  // angle and scale, so the window bounds the placement's translation (a unit error scales the drawing about its
  // own origin too).
  Eigen::Vector2d window_centre(std::size_t r) const {
    return Eigen::Vector2d(initial_.x_m, initial_.y_m) +
           rotations_[r].scale * (Eigen::Rotation2Dd(rotations_[r].theta) * centroid_drawn_);
  }
  Eigen::Vector2d centroid_world(const Candidate& c) const {
    return window_centre(c.rotation) +
           pyramid_.cell_m * Eigen::Vector2d(static_cast<double>(c.ox), static_cast<double>(c.oy));
  }

  // The samples at rotation r in search cells, before the window's offset.
  void discretize(std::size_t r, std::vector<Eigen::Vector2i>& points) const {
    const auto& rotation = rotations_[r];
    const Eigen::Matrix2d m = rotation.scale * Eigen::Rotation2Dd(rotation.theta).toRotationMatrix();
    points.resize(samples_.size());
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      const Eigen::Vector2d w = window_centre(r) + m * (samples_[i] - centroid_drawn_);
      const Eigen::Vector2d c = (w - pyramid_.origin_m) / pyramid_.cell_m;
      points[i] = {static_cast<int>(std::floor(c.x())), static_cast<int>(std::floor(c.y()))};
    }
  }

  float score(const std::vector<Eigen::Vector2i>& points, std::int64_t ox, std::int64_t oy, int level) {
    ++scored_;
    const Field& f = pyramid_.levels[static_cast<std::size_t>(level)];
    double sum = 0;
    for (const auto& p : points) sum += f.at(p.x() + ox, p.y() + oy);
    return static_cast<float>(sum / static_cast<double>(points.size()));
  }

  bool is_excluded(const Candidate& c) const {
    if (!excluded_) return false;
    const double dt = (centroid_world(c) - centroid_world(*excluded_)).norm();
    const double dtheta = std::remainder(rotations_[c.rotation].theta - rotations_[excluded_->rotation].theta, 2 * kPi);
    return dt < options_.separation_m && std::abs(dtheta) < options_.separation_rad;
  }

  bool stopped() {
    if (timed_out_ || cancelled_) return true;
    if (++checks_ % 128 == 0 && std::chrono::steady_clock::now() > deadline_) timed_out_ = true;
    return timed_out_;
  }

  void expand(const Candidate& c, int level, const std::vector<Eigen::Vector2i>& points) {
    if (level == 0) {
      if (c.score > best_score_ && !is_excluded(c)) {
        best_ = c;
        best_score_ = c.score;
      }
      return;
    }
    const std::int64_t half = std::int64_t{1} << (level - 1);
    Candidate children[4];
    int n = 0;
    for (const std::int64_t dy : {std::int64_t{0}, half})
      for (const std::int64_t dx : {std::int64_t{0}, half}) {
        const std::int64_t ox = c.ox + dx, oy = c.oy + dy;
        if (ox > window_ || oy > window_) continue;
        children[n++] = {c.rotation, ox, oy, score(points, ox, oy, level - 1)};
      }
    // Insertion sort, best first (std::sort on four trips GCC 12's array-bounds warning).
    for (int i = 1; i < n; ++i)
      for (int j = i; j > 0 && children[j].score > children[j - 1].score; --j) std::swap(children[j], children[j - 1]);
    for (int i = 0; i < n; ++i) {
      if (children[i].score <= best_score_) break;
      expand(children[i], level - 1, points);
      if (stopped()) return;
    }
  }

  const std::vector<Eigen::Vector2d>& samples_;
  Eigen::Vector2d centroid_drawn_;
  Similarity2D initial_;
  const Pyramid& pyramid_;
  std::vector<Rotation> rotations_;
  std::int64_t window_;
  const RegistrationOptions& options_;
  std::chrono::steady_clock::time_point deadline_;
  std::optional<Candidate> excluded_, best_;
  float best_score_ = 0;
  std::size_t scored_ = 0, checks_ = 0;
  bool timed_out_ = false, cancelled_ = false;
};

// Angles θ0 - range .. θ0 + range in steps of `step`; the whole circle once when the range reaches half a turn.
std::vector<double> angles(double theta0, double range, double step) {
  std::vector<double> result;
  if (range >= kPi) {
    const auto n = static_cast<std::int64_t>(std::ceil(kPi / step));
    for (std::int64_t j = -n; j < n; ++j)
      result.push_back(theta0 + kPi * static_cast<double>(j) / static_cast<double>(n));
    return result;
  }
  const auto n = static_cast<std::int64_t>(std::ceil(range / step));
  for (std::int64_t j = -n; j <= n; ++j)
    result.push_back(theta0 + (n == 0 ? 0.0 : range * static_cast<double>(j) / static_cast<double>(n)));
  return result;
}

// The dominant directions of buildings turn the rotation search into a few candidates: length-weighted histograms of
// directions (mod π, 0.5° bins) of the drawn edges and of the occupied cells (from the second moments of their
// occupied neighbours, weighted by how line-like those are) are cross-correlated; each peak δ gives the rotations
// δ and δ + π. nullopt when the correlation has no clear peak (a round building, too little seen): then every
// angle is searched.
constexpr int kDirectionBins = 360;

void add_direction(std::vector<double>& histogram, double angle, double weight) {
  double bin = std::fmod(angle, kPi) / kPi * kDirectionBins;
  if (bin < 0) bin += kDirectionBins;
  const auto low = static_cast<int>(std::floor(bin)) % kDirectionBins;
  const double frac = bin - std::floor(bin);
  histogram[static_cast<std::size_t>(low)] += weight * (1 - frac);
  histogram[static_cast<std::size_t>((low + 1) % kDirectionBins)] += weight * frac;
}

std::vector<double> smoothed(const std::vector<double>& histogram) {
  std::vector<double> out(histogram.size(), 0.0);
  for (int i = 0; i < kDirectionBins; ++i)
    for (int d = -3; d <= 3; ++d)
      out[static_cast<std::size_t>(i)] +=
          std::exp(-0.5 * d * d) * histogram[static_cast<std::size_t>((i + d + kDirectionBins) % kDirectionBins)];
  return out;
}

std::optional<std::vector<double>> direction_peaks(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                                   double occupied_probability) {
  std::vector<double> drawn(kDirectionBins, 0.0), seen(kDirectionBins, 0.0);
  for (const auto& e : edges) {
    const Eigen::Vector2d d = e.p1 - e.p0;
    if (d.norm() > 0) add_direction(drawn, std::atan2(d.y(), d.x()), d.norm());
  }
  const auto& g = observed.geometry;
  const auto occupied = [&](std::int64_t x, std::int64_t y) {
    return x >= 0 && y >= 0 && x < g.width() && y < g.height() &&
           observed.probability[static_cast<std::size_t>(y * g.width() + x)] > occupied_probability;
  };
  for (std::int64_t y = 0; y < g.height(); ++y)
    for (std::int64_t x = 0; x < g.width(); ++x) {
      if (!occupied(x, y)) continue;
      // The occupied neighbours within a disk of four cells: a square window, or a smaller disk, bends the
      // direction of a rasterised wall toward the grid's axes (a wall at 160° read as 150° with 5 × 5).
      double sxx = 0, syy = 0, sxy = 0;
      int n = 0;
      for (int dy = -4; dy <= 4; ++dy)
        for (int dx = -4; dx <= 4; ++dx)
          if ((dx || dy) && dx * dx + dy * dy <= 16 && occupied(x + dx, y + dy)) {
            sxx += dx * dx;
            syy += dy * dy;
            sxy += dx * dy;
            ++n;
          }
      if (n < 4) continue;
      const double anisotropy = std::hypot(sxx - syy, 2 * sxy) / (sxx + syy);
      add_direction(seen, 0.5 * std::atan2(2 * sxy, sxx - syy), anisotropy);
    }
  drawn = smoothed(drawn);
  seen = smoothed(seen);
  std::vector<double> correlation(kDirectionBins, 0.0);
  for (int k = 0; k < kDirectionBins; ++k)
    for (int i = 0; i < kDirectionBins; ++i)
      correlation[static_cast<std::size_t>(k)] +=
          seen[static_cast<std::size_t>((i + k) % kDirectionBins)] * drawn[static_cast<std::size_t>(i)];
  const double top = *std::max_element(correlation.begin(), correlation.end());
  const double mean = std::accumulate(correlation.begin(), correlation.end(), 0.0) / kDirectionBins;
  if (!(top > 1.5 * mean)) return std::nullopt;
  std::vector<std::pair<double, double>> peaks;  // (correlation, shift [rad])
  for (int k = 0; k < kDirectionBins; ++k) {
    const double c = correlation[static_cast<std::size_t>(k)];
    const double before = correlation[static_cast<std::size_t>((k + kDirectionBins - 1) % kDirectionBins)];
    const double after = correlation[static_cast<std::size_t>((k + 1) % kDirectionBins)];
    if (c < 0.5 * top || c < before || c <= after) continue;
    // Parabolic interpolation between the bins.
    const double curvature = before - 2 * c + after;
    const double offset = curvature < 0 ? 0.5 * (before - after) / curvature : 0.0;
    peaks.emplace_back(c, (k + offset) * kPi / kDirectionBins);
  }
  std::sort(peaks.begin(), peaks.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (peaks.size() > 4) peaks.resize(4);
  std::vector<double> shifts;
  for (const auto& p : peaks) shifts.push_back(p.second);
  return shifts;
}

// Occupied cells and element points, the data the refinement fits the drawn edges to.
std::vector<Eigen::Vector2d> observed_points(const ObservedMap& observed, double occupied_probability) {
  std::vector<Eigen::Vector2d> points = observed.element_points;
  const auto& g = observed.geometry;
  for (std::int64_t y = 0; y < g.height(); ++y)
    for (std::int64_t x = 0; x < g.width(); ++x)
      if (observed.probability[static_cast<std::size_t>(y * g.width() + x)] > occupied_probability)
        points.push_back(g.center_of({x, y}));
  return points;
}

// The covariance of a placement from that of the small similarity about `pivot` it was solved for, (dt, dθ, ds) with
// t' = m + (1 + ds)·R(dθ)·(t − m) + dt, θ' = θ + dθ, s' = s·(1 + ds). The scale's row and column are zero when held.
Eigen::Matrix4d placement_cov(const Similarity2D& placement, const Eigen::Vector2d& pivot, Eigen::Matrix4d correction,
                              bool with_scale) {
  if (!with_scale) {
    correction.row(3).setZero();
    correction.col(3).setZero();
  }
  const Eigen::Vector2d lever = Eigen::Vector2d(placement.x_m, placement.y_m) - pivot;
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  a.block<2, 2>(0, 0).setIdentity();
  a.block<2, 1>(0, 2) = perp(lever);
  a.block<2, 1>(0, 3) = lever;
  a(2, 2) = 1;
  a(3, 3) = placement.scale;
  return a * correction * a.transpose();
}

struct Refined {
  Similarity2D placement;
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();
  double rms_m = 0;
  std::size_t matched = 0;
};

// Gauss-Newton on point-to-line distances of the observed points to the nearest placed edge within a band that
// narrows from `band0` to two cells. The unknowns are a small similarity about the matched points' centroid m,
// x ↦ m + (1 + ds)·R(dθ)·(x − m) + dt, so the lever arms stay the building's size whatever the drawing's origin.
Refined refine(const std::vector<DrawnEdge>& edges, const std::vector<Eigen::Vector2d>& points, Similarity2D placement,
               double band0, double cell_m, bool with_scale) {
  Refined result;
  const int unknowns = with_scale ? 4 : 3;
  const double band_min = 2.0 * cell_m;
  double band = std::max(band0, band_min);
  struct Placed {
    Eigen::Vector2d a, dir, normal;
    double length;
  };
  std::vector<Placed> placed(edges.size());
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const auto& q : points) {
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  for (int iteration = 0; iteration < 40; ++iteration) {
    for (std::size_t i = 0; i < edges.size(); ++i) {
      const Eigen::Vector2d a = placement.transform_point(edges[i].p0), b = placement.transform_point(edges[i].p1);
      const double length = (b - a).norm();
      const Eigen::Vector2d dir = length > 0 ? Eigen::Vector2d((b - a) / length) : Eigen::Vector2d(1, 0);
      placed[i] = {a, dir, perp(dir), length};
    }
    // Edges by bucket of `bucket` m, each in every bucket its band-widened box touches.
    const double bucket = std::max(1.0, 2 * band);
    const std::int64_t points_box[4] = {static_cast<std::int64_t>(std::floor(lo.x() / bucket)) - 1,
                                        static_cast<std::int64_t>(std::floor(lo.y() / bucket)) - 1,
                                        static_cast<std::int64_t>(std::floor(hi.x() / bucket)) + 1,
                                        static_cast<std::int64_t>(std::floor(hi.y() / bucket)) + 1};
    std::unordered_map<std::int64_t, std::vector<std::uint32_t>> buckets;
    std::size_t entries = 0;  // bounded: an absurd plan must not exhaust memory here
    const auto key = [](std::int64_t bx, std::int64_t by) { return bx * 73856093LL ^ by * 19349663LL; };
    for (std::size_t i = 0; i < placed.size(); ++i) {
      const auto& e = placed[i];
      const Eigen::Vector2d b = e.a + e.dir * e.length;
      const auto x0 = static_cast<std::int64_t>(std::floor((std::min(e.a.x(), b.x()) - band) / bucket));
      const auto x1 = static_cast<std::int64_t>(std::floor((std::max(e.a.x(), b.x()) + band) / bucket));
      const auto y0 = static_cast<std::int64_t>(std::floor((std::min(e.a.y(), b.y()) - band) / bucket));
      const auto y1 = static_cast<std::int64_t>(std::floor((std::max(e.a.y(), b.y()) + band) / bucket));
      // Only where there are observed points: an edge's box is clipped to theirs.
      const auto cx0 = std::max(x0, points_box[0]), cx1 = std::min(x1, points_box[2]);
      const auto cy0 = std::max(y0, points_box[1]), cy1 = std::min(y1, points_box[3]);
      if (cx0 > cx1 || cy0 > cy1) continue;
      const auto cells = static_cast<std::size_t>((cx1 - cx0 + 1) * (cy1 - cy0 + 1));
      if (cells > 1'000'000 || entries + cells > 20'000'000) continue;  // absurd edges are left to the search
      entries += cells;
      for (auto by = cy0; by <= cy1; ++by)
        for (auto bx = cx0; bx <= cx1; ++bx) buckets[key(bx, by)].push_back(static_cast<std::uint32_t>(i));
    }
    struct Match {
      Eigen::Vector2d q, normal;
      double offset;  // n·x = offset on the placed edge's line
    };
    std::vector<Match> matches;
    Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
    for (const auto& q : points) {
      const auto it = buckets.find(key(static_cast<std::int64_t>(std::floor(q.x() / bucket)),
                                       static_cast<std::int64_t>(std::floor(q.y() / bucket))));
      if (it == buckets.end()) continue;
      double nearest = band;
      const Placed* match = nullptr;
      for (const auto i : it->second) {
        const auto& e = placed[i];
        const double u = e.dir.dot(q - e.a);
        if (u < -cell_m || u > e.length + cell_m) continue;
        const double d = std::abs(e.normal.dot(q - e.a));
        if (d < nearest) {
          nearest = d;
          match = &e;
        }
      }
      if (!match) continue;
      matches.push_back({q, match->normal, match->normal.dot(match->a)});
      centroid += q;
    }
    if (matches.size() < static_cast<std::size_t>(unknowns) + 1) break;
    centroid /= static_cast<double>(matches.size());
    Eigen::Matrix4d normal_matrix = Eigen::Matrix4d::Zero();
    Eigen::Vector4d gradient = Eigen::Vector4d::Zero();
    double weighted_sq = 0, weight_sum = 0;
    for (const auto& m : matches) {
      const double r = m.normal.dot(m.q) - m.offset;
      const double w = std::abs(r) <= cell_m ? 1.0 : cell_m / std::abs(r);  // Huber
      Eigen::Vector4d j(-m.normal.x(), -m.normal.y(), perp(m.normal).dot(m.q - centroid),
                        -(m.offset - m.normal.dot(centroid)));
      if (!with_scale) j(3) = 0;
      normal_matrix += w * j * j.transpose();
      gradient += w * j * r;
      weighted_sq += w * r * r;
      weight_sum += w;
    }
    if (!with_scale) normal_matrix(3, 3) = 1;
    const Eigen::Matrix4d inverse = normal_matrix.inverse();
    if (!inverse.allFinite()) break;
    const Eigen::Vector4d delta = -inverse * gradient;
    // Compose the correction after the placement.
    const Eigen::Vector2d t(placement.x_m, placement.y_m);
    const Eigen::Vector2d t_new =
        centroid + (1 + delta(3)) * (Eigen::Rotation2Dd(delta(2)) * (t - centroid)) + delta.head<2>();
    placement = {t_new.x(), t_new.y(), placement.theta_rad + delta(2), placement.scale * (1 + delta(3))};
    result.placement = placement;
    result.matched = matches.size();
    const double dof = std::max(1.0, static_cast<double>(matches.size()) - unknowns);
    const double sigma_sq = weighted_sq / dof;
    result.rms_m = std::sqrt(weighted_sq / std::max(weight_sum, 1.0));
    result.covariance = placement_cov(placement, centroid, sigma_sq * inverse, with_scale);
    const bool settled = delta.head<2>().norm() < 1e-4 && std::abs(delta(2)) < 1e-6 && std::abs(delta(3)) < 1e-7;
    if (settled && band <= band_min) break;
    band = std::max(band_min, band * 0.7);
  }
  if (result.matched == 0) result.placement = placement;
  return result;
}

}  // namespace

PlacementHypothesis score_placement(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                    const Similarity2D& placement, double occupied_probability) {
  const auto& g = observed.geometry;
  const double length_m = total_length(edges) * placement.scale;
  const auto count = static_cast<std::size_t>(std::clamp(length_m / g.resolution_m(), 1.0, 2.0e6));
  const auto samples = sample_edges(edges, count);
  std::size_t known = 0, on = 0;
  for (const auto& s : samples) {
    const auto w = placement.transform_point(s);
    if (!finite(w)) continue;
    const auto c = g.cell_of(w);
    bool seen = false, occupied = false;
    for (std::int64_t dy = -1; dy <= 1; ++dy)
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        const CellIndex n{c.x + dx, c.y + dy};
        if (!g.contains(n)) continue;
        const float p = observed.probability[static_cast<std::size_t>(n.y * g.width() + n.x)];
        if (std::isnan(p)) continue;
        seen = true;
        occupied = occupied || p > occupied_probability;
      }
    known += seen;
    on += occupied;
  }
  PlacementHypothesis h{placement, 0, 0};
  if (!samples.empty()) h.coverage = static_cast<double>(known) / static_cast<double>(samples.size());
  if (known > 0) h.score = static_cast<double>(on) / static_cast<double>(known);
  return h;
}

RegistrationResult register_plan(const std::vector<DrawnEdge>& edges, const ObservedMap& observed,
                                 const RegistrationOptions& options) {
  validate(edges, observed, options);
  const auto start = std::chrono::steady_clock::now();
  auto points = observed_points(observed, options.occupied_probability);
  if (points.size() == observed.element_points.size())
    throw RegistrationError("the grid has no occupied cell yet: nothing to place the plan against");

  const Pyramid pyramid = build_pyramid(observed, options.search_cell_m, options.occupied_probability);
  std::vector<double> scales = options.scale_candidates;
  const double drawn_length = total_length(edges);
  const auto search_samples = sample_edges(
      edges, std::min<std::size_t>(
                 options.max_samples,
                 static_cast<std::size_t>(std::max(
                     1.0, drawn_length * std::max(options.scale_max, options.initial.scale) / pyramid.cell_m))));
  Eigen::Vector2d centroid_drawn = Eigen::Vector2d::Zero();
  for (const auto& s : search_samples) centroid_drawn += s;
  centroid_drawn /= static_cast<double>(search_samples.size());
  double radius_drawn = 0;
  for (const auto& s : search_samples) radius_drawn = std::max(radius_drawn, (s - centroid_drawn).norm());
  radius_drawn = std::max(radius_drawn, 1e-9);

  const bool searching_scale = !options.scale_candidates.empty() || options.scale_min < options.scale_max;
  if (scales.empty()) {
    if (options.scale_min == options.scale_max) {
      scales.push_back(options.scale_min);
    } else {
      // One step moves the farthest point by one search cell.
      const double ratio = 1 + pyramid.cell_m / (radius_drawn * options.scale_max);
      const double steps = std::ceil(std::log(options.scale_max / options.scale_min) / std::log(ratio));
      if (steps > static_cast<double>(kMaxScaleSteps))
        throw RegistrationError("scale: the range needs " + std::to_string(static_cast<long long>(steps)) +
                                " steps at this plan's size (at most 256): narrow it or give candidates");
      for (double s = options.scale_min; s < options.scale_max * ratio; s *= ratio)
        scales.push_back(std::min(s, options.scale_max));
    }
  }
  // A scale that makes the drawing ten times larger than everything observed, or smaller than a few cells, cannot
  // be the answer (a unit candidate far off): not searched, unless nothing else is left.
  const double observed_radius =
      0.5 * observed.geometry.resolution_m() *
      std::hypot(static_cast<double>(observed.geometry.width()), static_cast<double>(observed.geometry.height()));
  std::vector<double> plausible;
  for (const double s : scales)
    if (s * radius_drawn <= 10 * observed_radius && s * radius_drawn >= 5 * pyramid.cell_m) plausible.push_back(s);
  if (!plausible.empty()) scales = std::move(plausible);
  const auto peaks =
      options.rotations_from_directions ? direction_peaks(edges, observed, options.occupied_probability) : std::nullopt;
  // What the bounds would cost, refused before anything is allocated for it: the angles each scale takes on the
  // path it will take (around the direction peaks, or every angle of the bound), and the root windows of all.
  const auto window = static_cast<std::int64_t>(std::ceil(options.max_translation_m / pyramid.cell_m));
  const double roots_per_rotation = std::pow(std::floor(2.0 * static_cast<double>(window) / (1 << kLevels)) + 1, 2);
  double rotation_count = 0;
  for (const double s : scales) {
    const double step = std::min(pyramid.cell_m / (radius_drawn * s), 0.1);
    const double sweep = 2 * std::ceil(std::min(options.max_rotation_rad, kPi) / step) + 1;
    rotation_count +=
        peaks ? std::min(sweep, 2.0 * static_cast<double>(peaks->size()) * (2 * std::ceil(kPeakHalfWidth / step) + 1))
              : sweep;
  }
  if (rotation_count > static_cast<double>(kMaxRotations) ||
      rotation_count * roots_per_rotation > static_cast<double>(kMaxRoots))
    throw RegistrationError("the bounds would take " + std::to_string(static_cast<long long>(rotation_count)) +
                            " rotations of " + std::to_string(static_cast<long long>(roots_per_rotation)) +
                            " translation windows (at most " + std::to_string(kMaxRotations) + " and " +
                            std::to_string(kMaxRoots) + " in all): narrow max_translation, max_rotation or the scale");
  std::vector<Rotation> rotations;
  for (const double s : scales) {
    const double step = std::min(pyramid.cell_m / (radius_drawn * s), 0.1);
    if (!peaks) {
      for (const double theta : angles(options.initial.theta_rad, options.max_rotation_rad, step))
        rotations.push_back({s, theta});
      continue;
    }
    const auto before = rotations.size();
    for (const double shift : *peaks)
      for (const double turn : {shift, shift + kPi}) {
        // The nearest equivalent of the peak to the initial heading, if the bound allows it.
        const double theta = options.initial.theta_rad + std::remainder(turn - options.initial.theta_rad, 2 * kPi);
        if (std::abs(theta - options.initial.theta_rad) > options.max_rotation_rad + kPeakHalfWidth) continue;
        for (const double t : angles(theta, kPeakHalfWidth, step))
          if (std::abs(t - options.initial.theta_rad) <= options.max_rotation_rad) rotations.push_back({s, t});
      }
    // No peak within a narrow bound: the bound itself is small, search all of it.
    if (rotations.size() == before)
      for (const double theta : angles(options.initial.theta_rad, options.max_rotation_rad, step))
        rotations.push_back({s, theta});
  }
  const auto deadline = start + options.time_budget;
  Search search(search_samples, centroid_drawn, options.initial, pyramid, std::move(rotations), window, options,
                deadline);

  RegistrationResult result;
  const auto best = search.run(0.0f, std::nullopt, 0.0, 0.8);
  if (!best) {
    result.timed_out = search.timed_out();
    result.cancelled = search.cancelled();
    result.hypotheses_scored = search.scored();
    result.best = {options.initial, 0, 0};
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  }
  const float best_search_score = best->score;
  const double band0 = std::max(0.3, 3 * pyramid.cell_m);
  const double cell = observed.geometry.resolution_m();
  const bool with_scale = searching_scale || options.refine_scale;
  const auto refined = refine(edges, points, search.placement(*best), band0, cell, with_scale);
  result.best = score_placement(edges, observed, refined.placement, options.occupied_probability);
  result.covariance = refined.covariance;
  result.rms_m = refined.rms_m;
  result.matched_points = refined.matched;

  if (!search.timed_out() && !search.cancelled()) {
    if (const auto second = search.run(0.7f * best_search_score, best, 0.8, 1.0)) {
      auto other = refine(edges, points, search.placement(*second), band0, cell, with_scale).placement;
      const Eigen::Vector2d c_best = refined.placement.transform_point(centroid_drawn);
      const Eigen::Vector2d c_other = other.transform_point(centroid_drawn);
      // A refinement that slid back onto the best is no other hypothesis: keep the search's own.
      if ((c_best - c_other).norm() < options.separation_m &&
          std::abs(std::remainder(other.theta_rad - refined.placement.theta_rad, 2 * kPi)) < options.separation_rad)
        other = search.placement(*second);
      result.runner_up = score_placement(edges, observed, other, options.occupied_probability);
      const double best_matched = result.best.score * result.best.coverage;
      const double other_matched = result.runner_up->score * result.runner_up->coverage;
      result.ambiguous = other_matched >= options.ambiguity_ratio * best_matched;
    }
  }
  result.timed_out = search.timed_out();
  result.cancelled = search.cancelled();
  result.hypotheses_scored = search.scored();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

PairsPlacement place_from_pairs(const std::vector<PointPair>& pairs, bool with_scale, double point_sigma_m) {
  if (pairs.size() < 2) throw RegistrationError("pairs: at least two point pairs are needed");
  // Dynamic sizes: Umeyama on Matrix2Xd trips a GCC 12 stringop-overread warning inside Eigen.
  Eigen::MatrixXd drawn(2, pairs.size()), world(2, pairs.size());
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!finite(pairs[i].drawn) || !finite(pairs[i].world))
      throw RegistrationError("pairs[" + std::to_string(i) + "]: expected finite coordinates");
    drawn.col(static_cast<Eigen::Index>(i)) = pairs[i].drawn;
    world.col(static_cast<Eigen::Index>(i)) = pairs[i].world;
  }
  const auto spread = [](const Eigen::MatrixXd& m) { return (m.colwise() - m.rowwise().mean()).norm(); };
  // Points closer than a millimetre (drawn: relative to the drawing's own extent) leave the rotation undetermined.
  if (spread(drawn) <= 1e-9 * std::max(1.0, drawn.cwiseAbs().maxCoeff()) || spread(world) < 1e-3)
    throw RegistrationError("pairs: the points coincide, so the rotation is undetermined");
  const Eigen::MatrixXd t = Eigen::umeyama(drawn, world, with_scale);
  PairsPlacement result;
  const double scale = t.block<2, 2>(0, 0).col(0).norm();
  result.placement = {t(0, 2), t(1, 2), std::atan2(t(1, 0), t(0, 0)), with_scale ? scale : 1.0};
  // Covariance by the same small similarity about the world points' centroid as the refinement uses.
  const Eigen::Vector2d centroid = world.rowwise().mean();
  Eigen::Matrix4d normal_matrix = Eigen::Matrix4d::Zero();
  double sq = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const Eigen::Vector2d placed = result.placement.transform_point(pairs[i].drawn);
    sq += (pairs[i].world - placed).squaredNorm();
    for (int axis = 0; axis < 2; ++axis) {
      Eigen::Vector4d j;
      j.head<2>() = Eigen::Vector2d::Unit(axis);
      j(2) = perp(placed - centroid)(axis);
      j(3) = with_scale ? (placed - centroid)(axis) : 0.0;
      normal_matrix += j * j.transpose();
    }
  }
  if (!with_scale) normal_matrix(3, 3) = 1;
  const auto unknowns = with_scale ? 4.0 : 3.0;
  const double dof = 2.0 * static_cast<double>(pairs.size()) - unknowns;
  result.rms_m = std::sqrt(sq / static_cast<double>(pairs.size()));
  const double sigma_sq = std::max(point_sigma_m * point_sigma_m, dof > 0 ? sq / dof : 0.0);
  result.covariance = placement_cov(result.placement, centroid, sigma_sq * normal_matrix.inverse(), with_scale);
  return result;
}

}  // namespace wm::fusion
