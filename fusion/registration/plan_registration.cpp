#include "fusion/registration/plan_registration.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <string>
#include <thread>

#include "fusion/registration/plan_registration_internal.h"

// The correlative search (branch and bound over a max-pooled pyramid) and register_plan, which drives it and the
// refinement.
namespace wm::fusion {
using namespace internal;
namespace {

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
  if (!(o.min_search_score >= 0 && o.min_search_score <= 1))
    throw RegistrationError("min_search_score: expected a number in [0, 1]");
  if (o.threads < 1 || o.threads > 256) throw RegistrationError("threads: expected 1 to 256");
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
  std::size_t root = 0;  // position of the root window it lies in, in the order the roots are handed out
};

// The order of the roots: the higher score, then the lower rotation index, row and column.
bool root_before(const Candidate& a, const Candidate& b) {
  if (a.score != b.score) return a.score > b.score;
  if (a.rotation != b.rotation) return a.rotation < b.rotation;
  if (a.oy != b.oy) return a.oy < b.oy;
  return a.ox < b.ox;
}

// The order that makes the answer the same whatever the number of threads and whichever thread finds what first:
// the higher score, then the earlier root, the lower row and column. Ranking ties by root means that a tie in a root
// handed out after the best leaf's is pruned at once (a plan that fits exactly scores 1 in many coarse windows).
bool ranks_before(const Candidate& a, const Candidate& b) {
  if (a.score != b.score) return a.score > b.score;
  if (a.root != b.root) return a.root < b.root;
  if (a.oy != b.oy) return a.oy < b.oy;
  return a.ox < b.ox;
}

// What score() answers for a window that cannot reach the bar it was scored against (below every real score).
constexpr float kDropped = -1.0f;

// Runs body(0) on the calling thread and body(1 .. n-1) on threads of their own, and rethrows the first exception
// any of them threw once all have ended (an exception must not end the process from a worker).
template <class Body>
void on_threads(std::size_t n, const Body& body) {
  std::exception_ptr error;
  std::mutex error_mutex;
  const auto guarded = [&](std::size_t t) {
    try {
      body(t);
    } catch (...) {
      const std::lock_guard lock(error_mutex);
      if (!error) error = std::current_exception();
    }
  };
  {
    std::vector<std::jthread> pool;
    for (std::size_t t = 1; t < n; ++t) pool.emplace_back(guarded, t);
    guarded(0);
  }
  if (error) std::rethrow_exception(error);
}

// Branch and bound over (rotation, window) on `threads` threads. Roots are scored for every rotation, sorted, and
// handed out best first; every thread prunes with the best leaf any of them has found. A window whose bound equals
// that leaf's score is kept only when its first leaf (its root, lowest row and column) ranks before that leaf, so the
// answer is the first leaf in ranks_before order whatever the threads did in which order.
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
        deadline_(deadline),
        threads_(std::max<std::size_t>(1, std::min<std::size_t>(options.threads, rotations_.size()))) {}

  // The first leaf in ranks_before order among those scoring above `floor`; leaves within the separation of
  // `excluded` are passed over. A window whose bound does not exceed `floor` is dropped with all it holds.
  std::optional<Candidate> run(float floor, const std::optional<Candidate>& excluded, double progress_from,
                               double progress_to) {
    excluded_ = excluded;
    floor_ = floor;
    best_score_.store(floor);
    best_.reset();
    std::vector<Worker> workers(threads_);
    const std::int64_t step = std::int64_t{1} << kLevels;

    // Roots, one rotation at a time per thread, kept per rotation so that their order does not depend on the threads.
    std::vector<std::vector<Candidate>> roots_of(rotations_.size());
    std::atomic<std::size_t> next_rotation{0};
    on_threads(threads_, [&](std::size_t t) {
      Worker& w = workers[t];
      for (std::size_t r; (r = next_rotation.fetch_add(1)) < rotations_.size();) {
        discretize(r, w.points);
        for (std::int64_t oy = -window_; oy <= window_; oy += step)
          for (std::int64_t ox = -window_; ox <= window_; ox += step)
            if (const float s = score(w, ox, oy, kLevels); s != kDropped) roots_of[r].push_back({r, ox, oy, s, 0});
        // The clock is read after every rotation's roots (at most kMaxRoots in all, bounded before the search).
        if (timed_out_.load() || std::chrono::steady_clock::now() > deadline_) {
          timed_out_ = true;
          return;
        }
      }
    });
    for (const auto& w : workers) scored_ += w.scored;
    if (timed_out_) return std::nullopt;
    std::vector<Candidate> roots;
    for (auto& of : roots_of) roots.insert(roots.end(), of.begin(), of.end());
    roots_of = {};
    std::sort(roots.begin(), roots.end(), root_before);
    for (std::size_t i = 0; i < roots.size(); ++i) roots[i].root = i;

    std::atomic<std::size_t> next_root{0};
    std::mutex progress_mutex;
    for (auto& w : workers) w.scored = 0;
    on_threads(threads_, [&](std::size_t t) {
      Worker& w = workers[t];
      for (std::size_t i; (i = next_root.fetch_add(1)) < roots.size();) {
        // Sorted: once a root is pruned, so is every one after it.
        if (pruned(roots[i]) || stopped(w)) return;
        if (i % 64 == 0 && options_.progress) {
          const std::lock_guard lock(progress_mutex);
          if (!cancelled_ && !options_.progress(progress_from + (progress_to - progress_from) * static_cast<double>(i) /
                                                                    static_cast<double>(roots.size())))
            cancelled_ = true;
          if (cancelled_) return;
        }
        discretize(roots[i].rotation, w.points);
        expand(roots[i], kLevels, w);
      }
    });
    for (const auto& w : workers) scored_ += w.scored;
    return best_;
  }

  // The placement of a leaf: the drawing's centroid at its cell, turned and scaled by its rotation.
  Similarity2D placement(const Candidate& c) const {
    const auto& r = rotations_[c.rotation];
    const Eigen::Vector2d centroid = centroid_world(c);
    const Eigen::Vector2d t = centroid - r.scale * (Eigen::Rotation2Dd(r.theta) * centroid_drawn_);
    return {t.x(), t.y(), r.theta, r.scale};
  }

  std::size_t scored() const { return scored_; }
  bool timed_out() const { return timed_out_; }
  bool cancelled() const { return cancelled_; }

 private:
  // What one thread holds: its counters and the samples of the rotation it works on.
  struct Worker {
    std::size_t scored = 0, checks = 0;
    std::vector<Eigen::Vector2i> points;
  };

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

  // Whether window c (its score a bound of its leaves') holds nothing better than the floor and the best leaf found.
  bool pruned(const Candidate& c) const {
    if (c.score <= floor_) return true;
    const float best = best_score_.load(std::memory_order_relaxed);
    if (c.score != best) return c.score < best;
    const std::lock_guard lock(best_mutex_);
    return best_ && !ranks_before(c, *best_);
  }

  // The window's mean field value over the samples, or kDropped as soon as the samples left, at 1 each, could no
  // longer lift it out of pruned(): most windows are dropped after a part of the samples once a good leaf is known.
  float score(Worker& w, std::int64_t ox, std::int64_t oy, int level) const {
    ++w.scored;
    const Field& f = pyramid_.levels[static_cast<std::size_t>(level)];
    const auto n = static_cast<double>(w.points.size());
    // Past this sum the window is kept; 1e-6 of a sample keeps the test on the safe side of the rounding.
    const double bar = std::max(static_cast<double>(floor_) * n,
                                static_cast<double>(best_score_.load(std::memory_order_relaxed)) * n - 1e-6);
    constexpr std::size_t kBlock = 64;
    double sum = 0;
    for (std::size_t i = 0; i < w.points.size(); ++i) {
      sum += f.at(w.points[i].x() + ox, w.points[i].y() + oy);
      if ((i + 1) % kBlock == 0 && sum + static_cast<double>(w.points.size() - i - 1) + 1e-6 < bar) return kDropped;
    }
    return static_cast<float>(sum / n);
  }

  bool is_excluded(const Candidate& c) const {
    if (!excluded_) return false;
    const double dt = (centroid_world(c) - centroid_world(*excluded_)).norm();
    const double dtheta = std::remainder(rotations_[c.rotation].theta - rotations_[excluded_->rotation].theta, 2 * kPi);
    return dt < options_.separation_m && std::abs(dtheta) < options_.separation_rad;
  }

  bool stopped(Worker& w) {
    if (timed_out_.load(std::memory_order_relaxed) || cancelled_.load(std::memory_order_relaxed)) return true;
    if (++w.checks % 128 == 0 && std::chrono::steady_clock::now() > deadline_) timed_out_ = true;
    return timed_out_.load(std::memory_order_relaxed);
  }

  // Takes leaf c as the best unless a thread has found one that ranks before it.
  void offer(const Candidate& c) {
    const std::lock_guard lock(best_mutex_);
    if (best_ && !ranks_before(c, *best_)) return;
    best_ = c;
    best_score_.store(c.score);
  }

  void expand(const Candidate& c, int level, Worker& w) {
    if (level == 0) {
      if (!pruned(c) && !is_excluded(c)) offer(c);
      return;
    }
    const std::int64_t half = std::int64_t{1} << (level - 1);
    Candidate children[4];
    int n = 0;
    for (const std::int64_t dy : {std::int64_t{0}, half})
      for (const std::int64_t dx : {std::int64_t{0}, half}) {
        const std::int64_t ox = c.ox + dx, oy = c.oy + dy;
        if (ox > window_ || oy > window_) continue;
        children[n++] = {c.rotation, ox, oy, score(w, ox, oy, level - 1), c.root};
      }
    // Insertion sort, best first (std::sort on four trips GCC 12's array-bounds warning).
    for (int i = 1; i < n; ++i)
      for (int j = i; j > 0 && children[j].score > children[j - 1].score; --j) std::swap(children[j], children[j - 1]);
    for (int i = 0; i < n; ++i) {
      if (pruned(children[i])) continue;  // a later one of equal score may rank before the best
      expand(children[i], level - 1, w);
      if (stopped(w)) return;
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
  std::size_t threads_;
  std::optional<Candidate> excluded_;
  float floor_ = 0;
  std::atomic<float> best_score_{0};  // best_'s score, or the floor while there is none: read without the lock
  mutable std::mutex best_mutex_;
  std::optional<Candidate> best_;
  std::size_t scored_ = 0;
  std::atomic<bool> timed_out_{false}, cancelled_{false};
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

}  // namespace

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
  const auto floor = static_cast<float>(options.min_search_score);
  const auto best = search.run(floor, std::nullopt, 0.0, 0.8);
  if (!best) {
    result.timed_out = search.timed_out();
    result.cancelled = search.cancelled();
    result.hypotheses_scored = search.scored();
    result.best = {options.initial, 0, 0};
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  }
  const float best_search_score = best->score;
  result.search_score = best_search_score;
  const double band0 = std::max(0.3, 3 * pyramid.cell_m);
  const double cell = observed.geometry.resolution_m();
  const bool with_scale = searching_scale || options.refine_scale;
  const auto refined = refine(edges, points, search.placement(*best), band0, cell, with_scale);
  result.best = score_placement(edges, observed, refined.placement, options.occupied_probability);
  result.covariance = refined.covariance;
  result.rms_m = refined.rms_m;
  result.matched_points = refined.matched;

  if (!search.timed_out() && !search.cancelled()) {
    if (const auto second = search.run(std::max(floor, 0.7f * best_search_score), best, 0.8, 1.0)) {
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

}  // namespace wm::fusion
