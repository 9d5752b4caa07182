// Thinning + Hough on occupancy rasters of 400×400 and 2000×2000 cells, ours side by side with OpenCV
// (cv::ximgproc::thinning, cv::HoughLines, cv::HoughLinesP) on the same thresholded image, in the same run, with
// each method's agreement with the known walls reported as counters. Run: build-bench/bin/grid_lines_bench.
//
// The rasters are synthetic buildings (tests/fusion/grid_lines/synthetic_raster.h): rooms with doors, walls 3 cells
// thick, turned furniture 1–2 cells thick, occupancy noise, holes and speckles, so the truth is known exactly.
// Agreement:
//  - Hough lines (infinite; ours: hough_peaks with NMS, OpenCV: HoughLines, which has none): `recall` = fraction of
//    true walls longer than 0.5 m with a line within one bin (1 cell across at the wall's midpoint, 1°);
//    `precision` = fraction of the lines within one bin of such a wall; `lines` = how many lines came out;
//    `recall_top2w` = recall of the strongest 2·(number of walls) lines only (both lists come strongest first).
//  - Segments (ours: extract_grid_lines, OpenCV: HoughLinesP): `recall` = fraction of walls found within the
//    digitisation tolerance of the tests (2 cm and 0.5°, widened to half a cell across and half a cell over the
//    wall's length), `spurious` = segments longer than 0.3 m on no wall.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc.hpp>
#include <vector>

#include "bench/support/ratio_reporter.h"
#include "fusion/grid_lines/grid_line_extractor.h"
#include "fusion/grid_lines/hough.h"
#include "fusion/grid_lines/thinning.h"
#include "tests/fusion/grid_lines/synthetic_raster.h"

namespace {

using wm::fusion::LineFeature;
using wm::fusion::LineSegment;
using wm::fusion::testing::offset_at_wall;
using wm::fusion::testing::SyntheticMap;
using wm::fusion::testing::TrueWall;

constexpr double kDeg = std::numbers::pi / 180;
constexpr double kResolution = 0.05;
constexpr double kMinVotes = 10.0;  // 0.5 m of skeleton: the same vote threshold for both transforms

// A building whose raster is about n × n cells: 4 × 4 rooms for 400, 21 × 21 for 2000.
const SyntheticMap& building(int n) {
  static std::map<int, SyntheticMap> cache;
  auto it = cache.find(n);
  if (it == cache.end()) {
    const int rooms = n <= 400 ? 4 : 21;
    const double room_m = (n * kResolution - 1.0) / rooms;
    it = cache.emplace(n, wm::fusion::testing::building(11, rooms, rooms, room_m, kResolution)).first;
  }
  return it->second;
}

std::vector<TrueWall> long_walls(const SyntheticMap& map) { return wm::fusion::testing::longer_than(map.walls, 0.5); }

double angle_to(const TrueWall& w, const LineFeature& l) {
  return wm::fusion::testing::difference(w.line(), l).phi_rad;
}

bool within_a_bin(const TrueWall& w, const LineFeature& l) {
  return offset_at_wall(w, l) <= kResolution && angle_to(w, l) <= 1.0 * kDeg;
}

// Fraction of lines within one Hough bin of some wall longer than 0.5 m.
double line_precision(const std::vector<TrueWall>& walls, const std::vector<LineFeature>& lines) {
  std::size_t hit = 0;
  for (const LineFeature& l : lines) {
    hit += std::any_of(walls.begin(), walls.end(), [&](const TrueWall& w) { return within_a_bin(w, l); }) ? 1 : 0;
  }
  return lines.empty() ? 0.0 : static_cast<double>(hit) / static_cast<double>(lines.size());
}

// Fraction of walls with an infinite line within one Hough bin.
double line_recall(const std::vector<TrueWall>& walls, const std::vector<LineFeature>& lines) {
  std::size_t hit = 0;
  for (const TrueWall& w : walls) {
    hit += std::any_of(lines.begin(), lines.end(), [&](const LineFeature& l) { return within_a_bin(w, l); }) ? 1 : 0;
  }
  return walls.empty() ? 0.0 : static_cast<double>(hit) / static_cast<double>(walls.size());
}

// Agreement of segments with the walls longer than 0.5 m, as the tests measure it (found within the digitisation
// tolerance; spurious segments).
void report_segments(benchmark::State& state, const SyntheticMap& map, const std::vector<LineSegment>& segments) {
  const std::vector<TrueWall> walls = long_walls(map);
  const std::size_t found = wm::fusion::testing::count_found(walls, segments, kResolution);
  state.counters["recall"] = walls.empty() ? 0.0 : static_cast<double>(found) / static_cast<double>(walls.size());
  state.counters["spurious"] = static_cast<double>(wm::fusion::testing::spurious_segments(map, segments).size());
  state.counters["segments"] = static_cast<double>(segments.size());
}

// Our pre-processing, shared by both sides so that they thin the very same image.
std::vector<std::uint8_t> occupied_image(const SyntheticMap& map) {
  std::vector<std::uint8_t> image = wm::fusion::threshold(map.raster, wm::fusion::GridLineOptions{}.p_occupied);
  const auto& g = map.raster.geometry;
  wm::fusion::fill_small_holes(image, g.width(), g.height(), wm::fusion::GridLineOptions{}.max_hole_cells);
  return image;
}

cv::Mat as_mat(const std::vector<std::uint8_t>& image, const wm::fusion::GridGeometry& g) {
  cv::Mat m(static_cast<int>(g.height()), static_cast<int>(g.width()), CV_8UC1);
  for (std::size_t i = 0; i < image.size(); ++i) m.data[i] = image[i] != 0 ? 255 : 0;
  return m;
}

// Pixel (x, y) of the image is cell (x, y): its centre is at origin + (x + 0.5, y + 0.5)·Δ.
Eigen::Vector2d world_of_pixel(const wm::fusion::GridGeometry& g, double x, double y) {
  return g.origin_m() + Eigen::Vector2d(x + 0.5, y + 0.5) * g.resolution_m();
}

LineFeature world_line_of_cv(const wm::fusion::GridGeometry& g, float rho, float theta) {
  const double c = std::cos(theta), s = std::sin(theta);
  const Eigen::Vector2d foot = world_of_pixel(g, rho * c, rho * s);
  return LineFeature{foot.x() * c + foot.y() * s, static_cast<double>(theta), Eigen::Matrix2d::Zero()}.normalized();
}

std::vector<LineFeature> opencv_hough(const cv::Mat& skeleton, const wm::fusion::GridGeometry& g) {
  std::vector<cv::Vec2f> raw;
  cv::HoughLines(skeleton, raw, 1.0, std::numbers::pi / 180, static_cast<int>(kMinVotes));
  std::vector<LineFeature> lines;
  for (const auto& l : raw) lines.push_back(world_line_of_cv(g, l[0], l[1]));
  return lines;
}

std::vector<LineSegment> opencv_hough_p(const cv::Mat& skeleton, const wm::fusion::GridGeometry& g) {
  const wm::fusion::GridLineOptions options;
  std::vector<cv::Vec4i> raw;
  cv::HoughLinesP(skeleton, raw, 1.0, std::numbers::pi / 180, static_cast<int>(kMinVotes),
                  options.min_length_m / kResolution, options.max_gap_m / kResolution);
  std::vector<LineSegment> segments;
  for (const auto& l : raw) {
    const Eigen::Vector2d a = world_of_pixel(g, l[0], l[1]), b = world_of_pixel(g, l[2], l[3]);
    if ((b - a).norm() < 1e-6) continue;
    segments.push_back(LineSegment::from_points(a, b, Eigen::Matrix2d::Identity() * 1e-6));
  }
  return segments;
}

std::vector<LineFeature> our_hough(const SyntheticMap& map, const std::vector<std::uint8_t>& skeleton) {
  wm::fusion::HoughOptions options;
  options.min_votes = kMinVotes;
  std::vector<LineFeature> lines;
  for (const auto& p : wm::fusion::hough_peaks(map.raster, skeleton, options)) {
    lines.push_back(LineFeature{p.rho_m, p.phi_rad, Eigen::Matrix2d::Zero()});
  }
  return lines;
}

// Agreement of a list of lines, strongest first: over all of them, and over the strongest 2·(number of walls) only,
// where near-duplicates of one wall cost places (recall at K: OpenCV's HoughLines has no suppression).
void report_lines(benchmark::State& state, const SyntheticMap& map, const std::vector<LineFeature>& lines) {
  const std::vector<TrueWall> walls = long_walls(map);
  const std::vector<LineFeature> top(
      lines.begin(), lines.begin() + static_cast<std::ptrdiff_t>(std::min(lines.size(), 2 * walls.size())));
  state.counters["recall"] = line_recall(walls, lines);
  state.counters["precision"] = line_precision(walls, lines);
  state.counters["lines"] = static_cast<double>(lines.size());
  state.counters["recall_top2w"] = line_recall(walls, top);
}

void set_size(benchmark::State& state, const SyntheticMap& map) {
  state.SetItemsProcessed(state.iterations());  // items = rasters
  state.counters["cells"] = static_cast<double>(map.raster.p.size());
}

void BM_OursThinning(benchmark::State& state) {
  const SyntheticMap& map = building(static_cast<int>(state.range(0)));
  const auto image = occupied_image(map);
  const auto& g = map.raster.geometry;
  for (auto _ : state) benchmark::DoNotOptimize(wm::fusion::zhang_suen_thinning(image, g.width(), g.height()));
  set_size(state, map);
}

void BM_OpenCvThinning(benchmark::State& state) {
  const SyntheticMap& map = building(static_cast<int>(state.range(0)));
  const cv::Mat image = as_mat(occupied_image(map), map.raster.geometry);
  cv::Mat skeleton;
  for (auto _ : state) {
    cv::ximgproc::thinning(image, skeleton, cv::ximgproc::THINNING_ZHANGSUEN);
    benchmark::DoNotOptimize(skeleton.data);
  }
  set_size(state, map);
}

void BM_OursThinningHough(benchmark::State& state) {
  const SyntheticMap& map = building(static_cast<int>(state.range(0)));
  const auto image = occupied_image(map);
  const auto& g = map.raster.geometry;
  std::vector<LineFeature> lines;
  for (auto _ : state) {
    lines = our_hough(map, wm::fusion::zhang_suen_thinning(image, g.width(), g.height()));
    benchmark::DoNotOptimize(lines.data());
  }
  set_size(state, map);
  report_lines(state, map, lines);
}

void BM_OpenCvThinningHough(benchmark::State& state) {
  const SyntheticMap& map = building(static_cast<int>(state.range(0)));
  const cv::Mat image = as_mat(occupied_image(map), map.raster.geometry);
  cv::Mat skeleton;
  std::vector<LineFeature> lines;
  for (auto _ : state) {
    cv::ximgproc::thinning(image, skeleton, cv::ximgproc::THINNING_ZHANGSUEN);
    lines = opencv_hough(skeleton, map.raster.geometry);
    benchmark::DoNotOptimize(lines.data());
  }
  set_size(state, map);
  report_lines(state, map, lines);
}

void BM_OursExtractSegments(benchmark::State& state) {
  const SyntheticMap& map = building(static_cast<int>(state.range(0)));
  std::vector<LineSegment> segments;
  // The synthetic building is drawn (walls painted about their axes): its lines go through their bands' centres.
  wm::fusion::GridLineOptions drawn;
  drawn.place_on_surface = false;
  for (auto _ : state) {
    segments = wm::fusion::extract_grid_lines(map.raster, drawn);
    benchmark::DoNotOptimize(segments.data());
  }
  set_size(state, map);
  report_segments(state, map, segments);
}

void BM_OpenCvThinningHoughP(benchmark::State& state) {
  const SyntheticMap& map = building(static_cast<int>(state.range(0)));
  const cv::Mat image = as_mat(occupied_image(map), map.raster.geometry);
  cv::Mat skeleton;
  std::vector<LineSegment> segments;
  for (auto _ : state) {
    cv::ximgproc::thinning(image, skeleton, cv::ximgproc::THINNING_ZHANGSUEN);
    segments = opencv_hough_p(skeleton, map.raster.geometry);
    benchmark::DoNotOptimize(segments.data());
  }
  set_size(state, map);
  report_segments(state, map, segments);
}

#define WM_SIZES ->Arg(400)->Arg(2000)->Unit(benchmark::kMillisecond)
BENCHMARK(BM_OursThinning) WM_SIZES;
BENCHMARK(BM_OpenCvThinning) WM_SIZES;
BENCHMARK(BM_OursThinningHough) WM_SIZES;
BENCHMARK(BM_OpenCvThinningHough) WM_SIZES;
BENCHMARK(BM_OursExtractSegments) WM_SIZES;
BENCHMARK(BM_OpenCvThinningHoughP) WM_SIZES;

}  // namespace

int main(int argc, char** argv) {
  return wm::bench::run_with_ratios(
      argc, argv,
      {{"400 x 400 against OpenCV thinning + HoughLines", "BM_OpenCvThinningHough/400"},
       {"2000 x 2000 against OpenCV thinning + HoughLines", "BM_OpenCvThinningHough/2000"}});
}
