#include "fusion/grid_lines/grid_line_extractor.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <queue>
#include <stdexcept>
#include <string>

#include "fusion/grid_lines/internal/hough_accumulator.h"
#include "fusion/grid_lines/internal/raster_frame.h"
#include "fusion/grid_lines/internal/raster_lines.h"
#include "fusion/grid_lines/thinning.h"
#include "fusion/kalman/line_map.h"
#include "fusion/lines/line_fit.h"

namespace wm::fusion {
namespace {

using internal::CellLine;
using internal::HoughBin;

[[noreturn]] void fail(const std::string& message) {
  throw std::invalid_argument("validate(GridLineOptions): " + message);
}

bool in_range(double v, double lo, double hi) { return v >= lo && v <= hi; }

// A refined line has settled when it moves less than this between rounds.
constexpr double kSettledAngleRad = 1e-4;
constexpr double kSettledRhoCells = 0.01;

// A skeleton cell near a line, with its coordinate along it [cells].
struct Member {
  std::int64_t x = 0;
  std::int64_t y = 0;
  double t = 0.0;
};

// A run of members [begin, end) without a gap, spanning [t_lo, t_hi] along the line [cells].
struct Run {
  std::size_t begin = 0;
  std::size_t end = 0;
  double t_lo = 0.0;
  double t_hi = 0.0;
  std::size_t size() const { return end - begin; }
};

// A weighted fit over the occupied cells across a run.
struct Fit {
  LineFeature line;  // world, with C_L
  CellLine cell;     // the same line in the centred cell frame
  double t0_m = 0.0;
  double t1_m = 0.0;
};

// The point of `from` at coordinate t, expressed as the coordinate along `to` [cells].
double along_other(const CellLine& from, const CellLine& to, double t) {
  const double xc = from.rho * from.cos_theta - t * from.sin_theta;
  const double yc = from.rho * from.sin_theta + t * from.cos_theta;
  return to.along(xc, yc);
}

// A peak waiting in the queue; ordered by votes, then by bin index so the order is deterministic.
struct Candidate {
  float votes = 0.0f;
  std::size_t index = 0;
  HoughBin bin;
  bool operator<(const Candidate& other) const {
    return votes != other.votes ? votes < other.votes : index > other.index;
  }
};

class Extractor {
 public:
  Extractor(const ProbabilityRaster& raster, const GridLineOptions& options)
      : raster_(raster),
        options_(options),
        width_(raster.geometry.width()),
        height_(raster.geometry.height()),
        resolution_m_(raster.geometry.resolution_m()),
        gap_cells_(options.max_gap_m / raster.geometry.resolution_m()),
        acc_(width_, height_, options.hough.rho_step_cells, options.hough.theta_step_rad) {}

  std::vector<LineSegment> run() {
    occupied_ = threshold(raster_, options_.p_occupied);
    // The fit keeps the thresholded cells as they are (a filled hole may be unknown, without a probability).
    std::vector<std::uint8_t> filled = occupied_;
    fill_small_holes(filled, width_, height_, options_.max_hole_cells);
    skeleton_ = zhang_suen_thinning(filled, width_, height_);
    acc_.vote_cells(skeleton_.size(), [&](std::size_t i) { return skeleton_[i] != 0 ? 1.0f : 0.0f; });

    const internal::NmsWindow window = internal::nms_window(acc_, resolution_m_, options_.hough);
    const auto min_votes = static_cast<float>(options_.hough.min_votes);
    std::priority_queue<Candidate> queue;
    for (const HoughBin& b : internal::nms_peaks(acc_, min_votes, window)) queue.push({acc_.at(b), acc_.index(b), b});
    std::vector<std::uint8_t> retired(acc_.size(), 0);
    internal::GreyVotes grey(acc_, raster_, options_.hough.grey_min_p);

    // Lazy greedy: votes only ever drop (claimed cells leave the accumulator), so a candidate whose current votes
    // still match its key is the strongest line left.
    while (!queue.empty()) {
      const Candidate top = queue.top();
      queue.pop();
      if (retired[top.index] != 0) continue;
      const float votes = acc_.at(top.bin);
      if (votes < min_votes) continue;
      if (votes < top.votes) {
        queue.push({votes, top.index, top.bin});
        continue;
      }
      const HoughBin chosen =
          internal::resolve_ambiguity(acc_, top.bin, window, options_.hough.ambiguous_ratio, retired, grey).bin;
      retired[acc_.index(chosen)] = 1;
      if (!take_line(acc_.line(chosen))) continue;
      // What is left of this line (collinear pieces the first collection missed, a wall the NMS window hid)
      // competes again through the best remaining bin of the window.
      std::optional<HoughBin> next;
      internal::for_each_in_window(acc_, chosen, window, [&](HoughBin b) {
        if (retired[acc_.index(b)] == 0 && acc_.at(b) >= min_votes && (!next || acc_.at(b) > acc_.at(*next))) next = b;
      });
      if (next) queue.push({acc_.at(*next), acc_.index(*next), *next});
    }
    return std::move(segments_);
  }

 private:
  std::size_t cell_index(std::int64_t x, std::int64_t y) const { return static_cast<std::size_t>(y * width_ + x); }

  // Unclaimed skeleton cells within `band` of the line, sorted along it.
  std::vector<Member> members(const CellLine& line) const {
    std::vector<Member> out;
    internal::for_each_cell_near_line(width_, height_, line, options_.member_band_cells,
                                      [&](std::int64_t x, std::int64_t y, double, double t) {
                                        if (skeleton_[cell_index(x, y)] != 0) out.push_back({x, y, t});
                                      });
    std::sort(out.begin(), out.end(), [](const Member& a, const Member& b) { return a.t < b.t; });
    return out;
  }

  std::vector<Run> split(const std::vector<Member>& m) const {
    std::vector<Run> runs;
    for (std::size_t i = 0; i < m.size(); ++i) {
      if (runs.empty() || m[i].t - m[i - 1].t > gap_cells_) runs.push_back({i, i, m[i].t, m[i].t});
      runs.back().end = i + 1;
      runs.back().t_hi = m[i].t;
    }
    return runs;
  }

  // Takes every segment the skeleton offers along a Hough line; true when at least one was accepted.
  bool take_line(const CellLine& line) {
    const std::vector<Member> m = members(line);
    std::vector<Run> runs = split(m);
    std::stable_sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.size() > b.size(); });
    bool taken = false;
    for (const Run& run : runs) {
      if (run.size() < options_.min_cells) break;
      // An earlier run of this line may have claimed cells of this one while it was being followed.
      const auto unclaimed = std::count_if(m.begin() + static_cast<std::ptrdiff_t>(run.begin),
                                           m.begin() + static_cast<std::ptrdiff_t>(run.end),
                                           [&](const Member& c) { return skeleton_[cell_index(c.x, c.y)] != 0; });
      if (static_cast<std::size_t>(unclaimed) < options_.min_cells) continue;
      if (follow(line, run.t_lo, run.t_hi)) taken = true;
    }
    return taken;
  }

  // Refines a run into a segment (fit, re-collect along the fit, repeat), then claims its cells.
  bool follow(CellLine line, double t_lo, double t_hi) {
    std::size_t run_cells = 0;
    for (int iteration = 0; iteration < options_.refine_iterations; ++iteration) {
      const std::optional<Fit> f = fit(line, t_lo, t_hi);
      if (!f) return false;
      const double a = along_other(line, f->cell, t_lo);
      const double b = along_other(line, f->cell, t_hi);
      const double lo = std::min(a, b);
      const double hi = std::max(a, b);
      const std::vector<Member> m = members(f->cell);
      const Run* best = nullptr;
      double best_overlap = -std::numeric_limits<double>::infinity();
      const std::vector<Run> runs = split(m);
      for (const Run& r : runs) {
        const double overlap = std::min(hi, r.t_hi) - std::max(lo, r.t_lo);
        if (overlap > best_overlap) {
          best_overlap = overlap;
          best = &r;
        }
      }
      // The fitted line must still run along (or touch) the cells it came from.
      if (best == nullptr || best_overlap < -1.0) return false;
      // Settled when neither the run nor the line moves any more (a Hough line can start a few degrees off when
      // it passes through two parallel walls; each round brings the band closer to the wall).
      const bool same_run = std::abs(best->t_lo - lo) <= 0.5 && std::abs(best->t_hi - hi) <= 0.5;
      const bool same_line =
          std::abs(f->cell.cos_theta - line.cos_theta) + std::abs(f->cell.sin_theta - line.sin_theta) <
              kSettledAngleRad &&
          std::abs(f->cell.rho - line.rho) < kSettledRhoCells;
      line = f->cell;
      t_lo = best->t_lo;
      t_hi = best->t_hi;
      run_cells = best->size();
      if (same_run && same_line) break;
    }
    if (run_cells < options_.min_cells) return false;
    const std::optional<Fit> f = fit(line, t_lo, t_hi);
    if (!f) return false;
    LineSegment segment;
    segment.line = f->line;
    segment.t0_m = f->t0_m;
    segment.t1_m = f->t1_m;
    if (segment.length_m() < options_.min_length_m) return false;
    claim(f->cell, along_other(line, f->cell, t_lo), along_other(line, f->cell, t_hi));
    segments_.push_back(options_.place_on_surface ? on_surface(segment) : segment);
    return true;
  }

  // What a cell says of a point [m]: occupied (p >= p_occupied), free (seen, p < 0.5), or neither (unknown, outside
  // the raster, or in between).
  enum class Seen { occupied, free, neither };
  Seen seen_at(const Eigen::Vector2d& point) const {
    const CellIndex c = raster_.geometry.cell_of(point);
    if (!raster_.geometry.contains(c)) return Seen::neither;
    const float p = raster_.p[cell_index(c.x, c.y)];
    if (std::isnan(p)) return Seen::neither;
    if (p >= options_.p_occupied) return Seen::occupied;
    return p < 0.5f ? Seen::free : Seen::neither;
  }

  // The segment moved across to the surface the laser saw, when its band borders free space on one side only. The
  // laser's inverse model marks the cell of a return and cells up to half a cell in front of it, and a beam's cone
  // lays its hits on an arc that runs on behind an obliquely seen surface, so the band reaches 1–3 cells behind the
  // surface and its centre (the fit) lies 2–7 cm behind it; its free-side edge is the surface. Across the segment at
  // every cell along it, the occupied run through the line is followed out to both edges; a side is free when a free
  // cell lies within a cell past its edge. When most of those cuts are free on one side only (at least twice as
  // many as on the other side), the line moves parallel to the median centre of the first occupied cell on that side:
  // within half a cell of the surface wherever the surface lies in that cell. Its ends move in to the outermost cuts
  // that show that surface: at a corner the band of the crossing wall runs on behind the surface, which put the
  // band's end 5–12 cm past the corner. Free on both sides (a partition seen from both) or on neither (no free space
  // in the raster), the segment stays as fitted. The quantisation does not average out along an axis-aligned wall,
  // so the offset σ at the middle is floored at cell/√12.
  LineSegment on_surface(const LineSegment& segment) const {
    const double res = resolution_m_;
    const double step = 0.25 * res;
    const double reach = (options_.fit_band_cells + 2.0) * res;
    const Eigen::Vector2d n = segment.line.normal(), dir = segment.line.direction();
    const double length = segment.length_m();
    const auto cuts = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(length / res)));
    const double spacing = length / static_cast<double>(cuts);
    struct Cut {
      double t = 0.0;
      int free_side = -1;  // 0: free toward −n only, 1: toward +n only, −1: neither or both
      double front = 0.0;  // offset of the first occupied cell's centre on the free side [m]
    };
    std::vector<Cut> across;
    for (std::int64_t k = 0; k < cuts; ++k) {
      Cut cut;
      cut.t = segment.t0_m + (static_cast<double>(k) + 0.5) * spacing;
      const Eigen::Vector2d base = segment.line.rho_m * n + cut.t * dir;
      const auto at = [&](double d) { return seen_at(base + d * n); };
      // The occupied run through the line: from its occupied sample nearest the line.
      std::optional<double> start;
      for (double j = 0.0; j <= options_.fit_band_cells * res && !start; j += step) {
        if (at(-j) == Seen::occupied) {
          start = -j;
        } else if (at(j) == Seen::occupied) {
          start = j;
        }
      }
      if (!start) continue;
      double edge[2] = {*start, *start};
      bool free[2] = {false, false};
      for (int side = 0; side < 2; ++side) {
        const double sign = side == 0 ? -1.0 : 1.0;
        while (std::abs(edge[side] + sign * step) <= reach && at(edge[side] + sign * step) == Seen::occupied)
          edge[side] += sign * step;
        for (double j = step; j <= res + 1e-9 && !free[side]; j += step) {
          const Seen s = at(edge[side] + sign * j);
          if (s == Seen::occupied) break;
          free[side] = s == Seen::free;
        }
      }
      if (free[0] != free[1]) {
        cut.free_side = free[0] ? 0 : 1;
        const CellIndex c = raster_.geometry.cell_of(base + edge[cut.free_side] * n);
        cut.front = segment.line.signed_distance(raster_.geometry.center_of(c));
      }
      across.push_back(cut);
    }
    std::size_t count[2] = {0, 0};
    for (const Cut& cut : across)
      if (cut.free_side >= 0) ++count[cut.free_side];
    int side = -1;
    for (int s = 0; s < 2; ++s) {
      if (count[s] >= 3 && count[s] >= 2 * count[1 - s] && 2 * count[s] >= across.size()) side = s;
    }
    if (side < 0) return segment;
    std::vector<double> offsets;
    double t_lo = std::numeric_limits<double>::infinity(), t_hi = -t_lo;
    for (const Cut& cut : across) {
      if (cut.free_side != side) continue;
      offsets.push_back(cut.front);
      t_lo = std::min(t_lo, cut.t - 0.5 * spacing);
      t_hi = std::max(t_hi, cut.t + 0.5 * spacing);
    }
    std::nth_element(offsets.begin(), offsets.begin() + static_cast<std::ptrdiff_t>(offsets.size() / 2), offsets.end());
    const double shift = offsets[offsets.size() / 2];
    const Eigen::Vector2d a = (segment.line.rho_m + shift) * n + t_lo * dir;
    const Eigen::Vector2d b = (segment.line.rho_m + shift) * n + t_hi * dir;
    LineSegment moved;
    moved.line = LineFeature{segment.line.rho_m + shift, segment.line.phi_rad, segment.line.cov}.normalized();
    moved.t0_m = std::min(moved.line.coordinate_along(a), moved.line.coordinate_along(b));
    moved.t1_m = std::max(moved.line.coordinate_along(a), moved.line.coordinate_along(b));
    return with_covariance_floor(moved, {res / std::sqrt(12.0), 0.0});
  }

  // Weighted TLS over the occupied cells across [t_lo, t_hi] of the line, widened by the fit band (eq. 3
  // weights). The cells are cut into slices one cell wide across the line; a slice whose cells reach more than
  // slice_tolerance beyond the typical cross-section (the median of the slices' extents) holds something else
  // too — a wall joining at a corner or a T, a speck — and is left out, with its neighbours (a turned wall's
  // columns straddle two slices), as long as min_cells clean cells remain. nullopt when too few cells or no
  // dominant direction.
  std::optional<Fit> fit(const CellLine& line, double t_lo, double t_hi) const {
    struct Cell {
      std::int64_t x;
      std::int64_t y;
      double d;
      double t;
      std::size_t slice;
    };
    // The skeleton stops short of a wall's end by about half its thickness, so the fit reaches past the run;
    // slices a little farther out are looked at too, so that a corner just outside the fit range is seen.
    const double band = options_.fit_band_cells;
    const double start = t_lo - band;
    const double stop = t_hi + band;
    constexpr double kLook = 2.0;
    const double first = start - kLook;  // centre of slice 0 (t_lo is a cell's coordinate: slices sit on cells)
    const auto slices = static_cast<std::size_t>(std::floor(stop + kLook - first + 0.5)) + 1;
    // Cells are placed along the line by their row (or column, for a line nearer horizontal) rather than by their
    // own t: a cut across a tilted line would otherwise take part of a row at each end, and that part tilts the
    // next fit further the same way (the refinement then swings between two wrong lines). A row's t differs from a
    // cell's own by at most its distance from the line, so the walk reaches a band (plus a cell) farther.
    const double half_w = 0.5 * static_cast<double>(width_);
    const double half_h = 0.5 * static_cast<double>(height_);
    std::vector<Cell> cells;
    internal::for_each_cell_near_line(
        width_, height_, line, band, first - 0.5 - band - 1.0, stop + kLook + 0.5 + band + 1.0,
        [&](std::int64_t x, std::int64_t y, double d, double) {
          if (occupied_[cell_index(x, y)] == 0) return;
          const double t =
              line.along_by_row(static_cast<double>(x) + 0.5 - half_w, static_cast<double>(y) + 0.5 - half_h);
          if (t < first - 0.5 || t > stop + kLook + 0.5) return;
          const double k = std::clamp(std::floor(t - first + 0.5), 0.0, static_cast<double>(slices - 1));
          cells.push_back({x, y, d, t, static_cast<std::size_t>(k)});
        });
    constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
    std::vector<double> lo(slices, kNone), hi(slices, kNone);
    for (const Cell& c : cells) {
      lo[c.slice] = std::isnan(lo[c.slice]) ? c.d : std::min(lo[c.slice], c.d);
      hi[c.slice] = std::isnan(hi[c.slice]) ? c.d : std::max(hi[c.slice], c.d);
    }
    auto in_range = [&](double t) { return t >= start && t <= stop; };
    std::vector<double> los, his;
    for (std::size_t k = 0; k < slices; ++k) {
      if (!std::isnan(lo[k]) && in_range(first + static_cast<double>(k))) {
        los.push_back(lo[k]);
        his.push_back(hi[k]);
      }
    }
    if (los.empty()) return std::nullopt;
    auto median = [](std::vector<double>& v) {
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      return v[v.size() / 2];
    };
    const double typical_lo = median(los) - options_.slice_tolerance_cells;
    const double typical_hi = median(his) + options_.slice_tolerance_cells;
    std::vector<std::uint8_t> dirty(slices, 0);
    for (std::size_t k = 0; k < slices; ++k) {
      if (std::isnan(lo[k]) || (lo[k] >= typical_lo && hi[k] <= typical_hi)) continue;
      dirty[k] = 1;
      if (k > 0) dirty[k - 1] = 1;
      if (k + 1 < slices) dirty[k + 1] = 1;
    }
    std::erase_if(cells, [&](const Cell& c) { return !in_range(c.t); });
    const auto clean = static_cast<std::size_t>(
        std::count_if(cells.begin(), cells.end(), [&](const Cell& c) { return dirty[c.slice] == 0; }));
    const bool all = clean < options_.min_cells;
    std::vector<Eigen::Vector2d> points;
    std::vector<double> sigmas;
    for (const Cell& c : cells) {
      if (!all && dirty[c.slice] != 0) continue;
      points.push_back(raster_.geometry.center_of({c.x, c.y}));
      sigmas.push_back(grid_cell_sigma_m(resolution_m_, raster_.p[cell_index(c.x, c.y)]));
    }
    if (points.size() < 2) return std::nullopt;
    Fit result;
    try {
      result.line = fit_line(points, sigmas);
    } catch (const std::invalid_argument&) {
      return std::nullopt;  // coincident points or no dominant direction: not a line
    }
    result.cell = internal::cell_line(result.line, raster_.geometry);
    // The extent. Each slice's cells along the fitted line: their mean coordinate [m].
    std::vector<double> sum(slices, 0.0);
    std::vector<std::size_t> count(slices, 0);
    for (const Cell& c : cells) {
      sum[c.slice] += result.line.coordinate_along(raster_.geometry.center_of({c.x, c.y}));
      ++count[c.slice];
    }
    // A slice holding more than the typical cross-section at an end is another wall crossing there (a corner, a T):
    // the end is the innermost such slice, where that wall begins, and not its far side, which is as far past the
    // corner as the other wall is thick (with the laser's band behind a surface, 2–3 cells). At a free end, the
    // centre of the last cells: hits reach the wall's end somewhere inside that cell.
    // Crossing: beyond the typical cross-section and on to the band's edge (a wall that runs on across the band; a
    // thicker patch of this wall's own band, or a speck, does not reach it). Only the last slices can hold the
    // crossing wall that ends this one: as many as the band is wide, counted from the outermost cells inward.
    auto crossing = [&](std::size_t k) {
      return (lo[k] < typical_lo && lo[k] <= 1.0 - band) || (hi[k] > typical_hi && hi[k] >= band - 1.0);
    };
    const auto window = static_cast<std::ptrdiff_t>(std::ceil(2.0 * band)) + 1;
    auto end_at = [&](std::size_t from, std::size_t to, std::ptrdiff_t step) -> std::optional<double> {
      std::optional<std::size_t> outermost, innermost;
      for (auto k = static_cast<std::ptrdiff_t>(from); k != static_cast<std::ptrdiff_t>(to) + step; k += step) {
        const auto u = static_cast<std::size_t>(k);
        if (outermost && std::abs(k - static_cast<std::ptrdiff_t>(*outermost)) >= window) break;
        if (count[u] == 0) continue;
        if (!outermost) outermost = u;
        if (crossing(u)) innermost = u;
      }
      if (!outermost) return std::nullopt;
      const std::size_t k = innermost ? *innermost : *outermost;
      return sum[k] / static_cast<double>(count[k]);
    };
    std::optional<std::size_t> k_first, k_last;
    for (std::size_t k = 0; k < slices; ++k) {
      if (count[k] == 0) continue;
      if (!k_first) k_first = k;
      k_last = k;
    }
    if (!k_first) return std::nullopt;
    const std::optional<double> a = end_at(*k_first, *k_last, 1);
    const std::optional<double> b = end_at(*k_last, *k_first, -1);
    if (!a || !b) return std::nullopt;
    result.t0_m = std::min(*a, *b);
    result.t1_m = std::max(*a, *b);
    return result;
  }

  // Removes the skeleton cells a segment explains (within the fit band over its run, plus the fit's reach) from the
  // skeleton and their votes from the accumulator.
  void claim(const CellLine& line, double a, double b) {
    internal::for_each_cell_near_line(
        width_, height_, line, options_.fit_band_cells, std::min(a, b) - options_.fit_band_cells,
        std::max(a, b) + options_.fit_band_cells, [&](std::int64_t x, std::int64_t y, double, double) {
          std::uint8_t& s = skeleton_[cell_index(x, y)];
          if (s == 0) return;
          s = 0;
          acc_.add(x, y, -1.0f);
        });
  }

  const ProbabilityRaster& raster_;
  const GridLineOptions& options_;
  std::int64_t width_;
  std::int64_t height_;
  double resolution_m_;
  double gap_cells_;
  internal::HoughAccumulator acc_;
  std::vector<std::uint8_t> occupied_;
  std::vector<std::uint8_t> skeleton_;  // 1 = skeleton cell not yet claimed by a segment
  std::vector<LineSegment> segments_;
};

}  // namespace

void validate(const GridLineOptions& options) {
  if (!(options.p_occupied > 0.0f && options.p_occupied <= 1.0f)) fail("p_occupied must be in (0, 1]");
  if (options.max_hole_cells < 0) fail("max_hole_cells must be >= 0");
  validate(options.hough);
  if (!in_range(options.member_band_cells, 0.5, 10.0)) fail("member_band_cells must be in [0.5, 10]");
  if (!in_range(options.fit_band_cells, options.member_band_cells, 10.0)) {
    fail("fit_band_cells must be in [member_band_cells, 10]");
  }
  if (!in_range(options.slice_tolerance_cells, 0.0, 10.0)) fail("slice_tolerance_cells must be in [0, 10]");
  if (!(options.max_gap_m > 0.0) || !std::isfinite(options.max_gap_m)) fail("max_gap_m must be finite and > 0");
  if (!(options.min_length_m >= 0.0) || !std::isfinite(options.min_length_m)) {
    fail("min_length_m must be finite and >= 0");
  }
  if (options.min_cells < 2) fail("min_cells must be >= 2");
  if (options.refine_iterations < 1 || options.refine_iterations > 100) fail("refine_iterations must be in [1, 100]");
}

double grid_cell_sigma_m(double resolution_m, double p_occupied) {
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m)) {
    throw std::invalid_argument("grid_cell_sigma_m: resolution_m must be finite and > 0");
  }
  if (!(p_occupied > 0.0 && p_occupied <= 1.0)) {
    throw std::invalid_argument("grid_cell_sigma_m: p_occupied must be in (0, 1], got " + std::to_string(p_occupied));
  }
  return resolution_m / p_occupied;
}

std::vector<LineSegment> extract_grid_lines(const ProbabilityRaster& raster, const GridLineOptions& options) {
  validate(options);
  validate(raster);
  return Extractor(raster, options).run();
}

}  // namespace wm::fusion
