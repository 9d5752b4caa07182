#include "tools/truth/truth.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>

#include "common/diagnostics.h"
#include "fusion/grid/scan_geometry.h"
#include "logs/scan_body.h"
#include "rules/engine.h"
#include "server/storage/store.h"

namespace wm::truth {
namespace {

constexpr double kDeg = std::numbers::pi / 180;
constexpr double kOnLineM = 0.05, kOnLineRad = 3 * kDeg;  // "on a true line": the benchmark's tolerance
constexpr double kSampleM = 0.02;                         // element sample spacing, finer than a bin

struct Piece {
  Vec p0, p1;
  double length() const { return (p1 - p0).norm(); }
  std::size_t samples() const {
    return std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(length() / kSampleM)));
  }
  Vec sample(std::size_t k) const { return p0 + (p1 - p0) * ((k + 0.5) / static_cast<double>(samples())); }
};

std::vector<Piece> elements_of(const world::WorldState& state) {
  std::vector<Piece> pieces;
  for (const auto& [number, e] : state.elements) pieces.push_back({e.segment.p0(), e.segment.p1()});
  return pieces;
}

bool on_line(const Piece& e, const TrueLine& line) {
  return direction_difference(e.p1 - e.p0, line.p1 - line.p0) <= kOnLineRad &&
         segment_distance(e.p0, e.p1, line.p0, line.p1) <= kOnLineM;
}

/// Per line, per bin: the elements lying on it there (within 5 cm and 3°).
std::vector<std::vector<std::vector<std::size_t>>> covering(const std::vector<Piece>& elements,
                                                            const std::vector<TrueLine>& lines) {
  std::vector<std::vector<std::vector<std::size_t>>> cover(lines.size());
  for (std::size_t l = 0; l < lines.size(); ++l) cover[l].resize(bins_of((lines[l].p1 - lines[l].p0).norm()));
  // A sample covers the nearest true line it lies on: the element on one face of a wall 4 cm thick lies within 5 cm of
  // the other face too, and covers only its own.
  for (std::size_t i = 0; i < elements.size(); ++i) {
    std::vector<std::size_t> on;
    for (std::size_t l = 0; l < lines.size(); ++l)
      if (on_line(elements[i], lines[l])) on.push_back(l);
    for (std::size_t k = 0; k < elements[i].samples(); ++k) {
      const Vec p = elements[i].sample(k);
      std::size_t nearest = lines.size();
      double nearest_m = kOnLineM;
      for (const auto l : on) {
        const double d = point_segment_distance(p, lines[l].p0, lines[l].p1);
        if (d <= nearest_m) {
          nearest_m = d;
          nearest = l;
        }
      }
      if (nearest == lines.size()) continue;
      const Vec d = lines[nearest].p1 - lines[nearest].p0;
      const double length = d.norm();
      const double u = d.dot(p - lines[nearest].p0) / length;
      if (u < 0 || u > length) continue;
      auto& ids = cover[nearest][std::min(cover[nearest].size() - 1, static_cast<std::size_t>(u / kBinM))];
      if (std::find(ids.begin(), ids.end(), i) == ids.end()) ids.push_back(i);
    }
  }
  return cover;
}

Vec bin_centre(const Vec& p0, const Vec& p1, std::size_t bin) {
  const double length = (p1 - p0).norm();
  return p0 + (p1 - p0) * (std::min(length, (bin + 0.5) * kBinM) / length);
}

/// Element length within 0.3 m of a person's track that lies on no true line [m].
double people_elements(const std::vector<Piece>& elements, const BuiltWorld& world) {
  double length = 0;
  for (const auto& e : elements) {
    const double each = e.length() / static_cast<double>(e.samples());
    for (std::size_t k = 0; k < e.samples(); ++k) {
      const Vec p = e.sample(k);
      bool on_track = false;
      for (const auto& person : world.people)
        on_track = on_track || point_segment_distance(p, person.a, person.b) <= kPersonRadiusM + 0.1;
      if (!on_track) continue;
      bool on_truth = false;
      for (const auto& line : world.lines)
        on_truth = on_truth || point_segment_distance(p, line.p0, line.p1) <= kOnLineM;
      if (on_truth) continue;
      length += each;
      if (std::getenv("WM_TRUTH_VERBOSE"))
        std::fprintf(stderr, "by a person's track: (%.2f, %.2f) of the %.2f m element (%.2f, %.2f) to (%.2f, %.2f)\n",
                     p.x(), p.y(), e.length(), e.p0.x(), e.p0.y(), e.p1.x(), e.p1.y());
    }
  }
  return length;
}

std::string fixed(double value, int decimals) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  return buffer;
}

std::string optional_fixed(const std::optional<double>& value, int decimals) {
  return value ? fixed(*value, decimals) : "n/a";
}

// A replayed scan: its index in the drive, and where the server placed it.
struct PlacedScan {
  std::size_t index = 0;
  service::ScanPlacement placement;
};
// By the sequence number of the observation made of the scan's lines.
using Placements = std::map<std::int64_t, PlacedScan>;

// WM_TRUTH_TRACE: the decisions about some elements, on stderr, to follow how one came to be. "x,y": the elements
// within 10 cm of the point; "e12,e40": those elements; "bx0,y0,x1,y1": every decision whose observed segment has
// its middle in that box.
void trace_decisions(const char* trace, service::WorldService& world, const world::WorldState& state,
                     const Placements& placements) {
  std::set<std::string> ids;
  double bx0 = 0, by0 = 0, bx1 = -1, by1 = -1;
  if (trace[0] == 'e') {
    std::stringstream list(trace);
    for (std::string id; std::getline(list, id, ',');) ids.insert(id);
  } else if (trace[0] == 'b') {
    if (std::sscanf(trace + 1, "%lf,%lf,%lf,%lf", &bx0, &by0, &bx1, &by1) != 4) {
      std::fprintf(stderr, "WM_TRUTH_TRACE: a box is bX0,Y0,X1,Y1\n");
      return;
    }
    std::tie(bx0, bx1) = std::minmax({bx0, bx1});  // by value: minmax(a, b) returns references to a and b
    std::tie(by0, by1) = std::minmax({by0, by1});
  } else {
    double x = 0, y = 0;
    if (std::sscanf(trace, "%lf,%lf", &x, &y) != 2) {
      std::fprintf(stderr, "WM_TRUTH_TRACE: X,Y | eN,eM,... | bX0,Y0,X1,Y1\n");
      return;
    }
    for (const auto& [number, e] : state.elements)
      if (point_segment_distance(Vec(x, y), e.segment.p0(), e.segment.p1()) < 0.1) ids.insert(e.id());
  }
  const auto traced = [&](const world::DecisionRecord& d) {
    const Vec m = 0.5 * (d.p0 + d.p1);
    return (d.element && ids.count(*d.element)) || (d.matched_element && ids.count(*d.matched_element)) ||
           (m.x() >= bx0 && m.x() <= bx1 && m.y() >= by0 && m.y() <= by1);
  };
  for (const auto& d : world.decisions(0, 10'000'000, std::nullopt))
    if (traced(d)) {
      // Where the server placed the robot's scan (its posted pose aligned to the map).
      const auto at = placements.find(d.observation_seq);
      const auto robot = at != placements.end() ? at->second.placement.placed : fusion::Pose2D{};
      std::fprintf(stderr, "trace %lld %s el=%s matched=%s (%.2f,%.2f)-(%.2f,%.2f) robot (%.2f,%.2f) %s: %s\n",
                   static_cast<long long>(d.observation_seq), std::string(rules::wire_name(d.action)).c_str(),
                   d.element.value_or("-").c_str(), d.matched_element.value_or("-").c_str(), d.p0.x(), d.p0.y(),
                   d.p1.x(), d.p1.y(), robot.x_m, robot.y_m, d.rule.c_str(), d.explanation.c_str());
    }
}

// The returns of one replayed scan, in the world frame of the pose the server placed it at: "return SEQ BEAM X Y
// RANGE", one per line (`seq`: the sequence number of the observation made of its lines).
void print_scan_returns(const fusion::LaserScan& scan, const PlacedScan& placed, std::int64_t seq) {
  const auto pose = placed.placement.placed;
  for (std::size_t i = 0; i < scan.ranges_m.size(); ++i) {
    const double r = scan.ranges_m[i];
    if (!std::isfinite(r) || r < scan.range_min_m || r >= scan.range_max_m) continue;
    const double bearing = pose.theta_rad + fusion::beam_bearing_rad(scan, i);
    std::fprintf(stderr, "return %lld %zu %.3f %.3f %.3f\n", static_cast<long long>(seq), i,
                 pose.x_m + r * std::cos(bearing), pose.y_m + r * std::sin(bearing), r);
  }
}

// WM_TRUTH_SCAN: the returns of one scan ("SEQ") or of every scan ("all").
void print_returns(const std::vector<fusion::LaserScan>& scans, const Placements& placements, const char* which) {
  if (std::string_view(which) == "all") {
    for (const auto& [seq, placed] : placements) print_scan_returns(scans[placed.index], placed, seq);
  } else if (const auto at = placements.find(std::atoll(which)); at != placements.end()) {
    print_scan_returns(scans[at->second.index], at->second, at->first);
  }
}

// WM_TRUTH_GRID=x0,y0,x1,y1: the Bayes grid over that box at the end of the replay, a row of characters per row of
// cells from the top: '#' occupied (P > 0.65), '.' free (P < 0.25), '?' between, ' ' never seen.
void print_grid(const service::WorldService& world, const char* box) {
  double x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  if (std::sscanf(box, "%lf,%lf,%lf,%lf", &x0, &y0, &x1, &y1) != 4 || !(x1 > x0) || !(y1 > y0)) {
    std::fprintf(stderr, "WM_TRUTH_GRID: a box is X0,Y0,X1,Y1\n");
    return;
  }
  const double r = world.grid_resolution_m();
  const auto w = static_cast<std::int64_t>(std::ceil((x1 - x0) / r)),
             h = static_cast<std::int64_t>(std::ceil((y1 - y0) / r));
  const auto values = world.grid_layer(fusion::GridLayer::bayes, fusion::GridGeometry({x0, y0}, r, w, h)).values;
  for (std::int64_t y = h - 1; y >= 0; --y) {
    std::fprintf(stderr, "grid %8.2f ", y0 + (static_cast<double>(y) + 0.5) * r);
    for (std::int64_t x = 0; x < w; ++x) {
      const float p = values[static_cast<std::size_t>(y * w + x)];
      std::fputc(std::isnan(p) ? ' ' : p > 0.65f ? '#' : p < 0.25f ? '.' : '?', stderr);
    }
    std::fputc('\n', stderr);
  }
}

// How far the posted and the placed poses are from the true ones, over the scans the server placed, and the scans
// whose heading it made worse by more than the posted σ.
void print_alignment(const Drive& drove, const ReplayOutcome& mapped) {
  double posted_xy = 0, posted_th = 0, placed_xy = 0, placed_th = 0, worst_th = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < drove.scans.size() && i < mapped.placed.size(); ++i) {
    if (!mapped.placed[i]) continue;
    const auto& truth = drove.truth[i];
    const auto& posted = drove.scans[i].sensor_pose;
    const auto& placed = *mapped.placed[i];
    const auto error = [&](const fusion::Pose2D& p) {
      return std::pair{std::hypot(p.x_m - truth.x_m, p.y_m - truth.y_m),
                       std::abs(std::remainder(p.theta_rad - truth.theta_rad, 2 * std::numbers::pi))};
    };
    const auto [pxy, pth] = error(posted);
    const auto [axy, ath] = error(placed);
    posted_xy += pxy * pxy;
    posted_th += pth * pth;
    placed_xy += axy * axy;
    placed_th += ath * ath;
    worst_th = std::max(worst_th, ath);
    ++n;
    if (ath > pth + 0.2 * kDeg)
      std::fprintf(stderr, "alignment: scan %zu at (%.2f, %.2f) heading error %.2f deg posted, %.2f deg placed\n", i,
                   truth.x_m, truth.y_m, pth / kDeg, ath / kDeg);
  }
  if (n == 0) return;
  const double k = static_cast<double>(n);
  std::fprintf(stderr,
               "alignment: %zu scans, RMS error posted %.3f m / %.3f deg, placed %.3f m / %.3f deg, worst placed "
               "heading %.3f deg\n",
               n, std::sqrt(posted_xy / k), std::sqrt(posted_th / k) / kDeg, std::sqrt(placed_xy / k),
               std::sqrt(placed_th / k) / kDeg, worst_th / kDeg);
}

}  // namespace

const char* pose_noise_name(PoseNoise noise) { return noise == PoseNoise::low ? "low" : "high"; }

ReplayOutcome replay_scans(const std::vector<fusion::LaserScan>& scans, const Eigen::Matrix3d& pose_cov,
                           const std::optional<apriori::FloorPlan>& plan, const TruthOptions& options) {
  std::random_device random;
  const auto dir = std::filesystem::temp_directory_path() / ("wm-truth-" + std::to_string(random()));
  std::filesystem::create_directories(dir);
  struct Cleanup {
    std::filesystem::path path;
    ~Cleanup() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  } cleanup{dir};
  ReplayOutcome outcome;
  storage::StoreOptions store_options;
  store_options.path = (dir / "truth.db").string();
  store_options.synchronous_full = false;  // a benchmark can be run again
  storage::Store store(store_options);
  rules::EngineOptions engine_options;
  engine_options.rules_dir = options.rules_dir;
  rules::Engine engine(engine_options);
  common::Diagnostics diagnostics("wmd: ");  // on stderr as wmd has them; nobody asks for the counts
  {
    service::WorldService world(options.service, store, engine, diagnostics);
    if (plan) world.load_floor_plan(*plan);
    double stamp = 0;
    Placements placements;
    for (const auto& scan : scans) {
      world::ScanObservation request;
      request.observer = "truth";
      request.stamp_s = stamp;
      request.pose_cov = pose_cov;
      auto payload = logs::laser_scan_body(scan, request.observer, stamp).dump();
      request.scan = scan;
      const auto posted = world.post_scan(std::move(request), std::move(payload), std::nullopt);
      if (posted.placement)
        outcome.placed.push_back(posted.placement->placed);
      else
        outcome.placed.emplace_back();
      if (posted.lines && posted.placement) {
        placements.emplace(posted.lines->seq,
                           PlacedScan{static_cast<std::size_t>(&scan - scans.data()), *posted.placement});
      }
      stamp += 0.5;
    }
    outcome.state = world.snapshot();
    if (plan && std::getenv("WM_TRUTH_VERBOSE"))
      for (const auto& d : world.decisions(0, 1'000'000, std::nullopt))
        if (d.object.value_or(d.matched_object.value_or("")) == kTableId)
          std::fprintf(stderr, "table decision %lld: %s %s: %s\n", static_cast<long long>(d.observation_seq),
                       std::string(rules::wire_name(d.action)).c_str(), d.rule.c_str(), d.explanation.c_str());
    if (const char* trace = std::getenv("WM_TRUTH_TRACE")) trace_decisions(trace, world, *outcome.state, placements);
    if (const char* seq = std::getenv("WM_TRUTH_SCAN")) print_returns(scans, placements, seq);
    if (const char* box = std::getenv("WM_TRUTH_GRID")) print_grid(world, box);
    outcome.report = world.refresh_plan_report();  // the evidence of the last scans too, not only the last trim's
  }
  return outcome;
}

MappingScore score_mapping(const world::WorldState& state, const BuiltWorld& world, const Coverage& coverage) {
  MappingScore score;
  const auto elements = elements_of(state);
  score.elements = elements.size();
  double good = 0;
  for (const auto& e : elements) {
    score.element_length_m += e.length();
    std::vector<const TrueLine*> candidates;
    for (const auto& line : world.lines)
      if (on_line(e, line)) candidates.push_back(&line);
    const double each = e.length() / static_cast<double>(e.samples());
    double good_here = 0;
    for (std::size_t k = 0; k < e.samples(); ++k) {
      const Vec p = e.sample(k);
      for (const auto* line : candidates)
        if (point_segment_distance(p, line->p0, line->p1) <= kOnLineM) {
          good_here += each;
          break;
        }
    }
    good += good_here;
    if (std::getenv("WM_TRUTH_VERBOSE") && good_here < e.length() - 1e-9) {
      double nearest = 1e9, angle = 0;
      for (const auto& line : world.lines) {
        const double d = segment_distance(e.p0, e.p1, line.p0, line.p1);
        if (d < nearest) {
          nearest = d;
          angle = direction_difference(e.p1 - e.p0, line.p1 - line.p0);
        }
      }
      std::fprintf(stderr,
                   "off the walls: %.2f of %.2f m from (%.2f, %.2f) to (%.2f, %.2f), nearest wall %.3f m, %.1f deg\n",
                   e.length() - good_here, e.length(), e.p0.x(), e.p0.y(), e.p1.x(), e.p1.y(), nearest,
                   angle * 180 / 3.141592653589793);
      for (const auto& line : world.lines)
        if (segment_distance(e.p0, e.p1, line.p0, line.p1) < 0.3)
          std::fprintf(stderr, "    true wall (%.2f, %.2f) to (%.2f, %.2f)\n", line.p0.x(), line.p0.y(), line.p1.x(),
                       line.p1.y());
    }
  }
  const auto cover = covering(elements, world.lines);
  double redundant = 0, recalled = 0, recalled_all = 0, walls_elements = 0;
  for (std::size_t l = 0; l < world.lines.size(); ++l) {
    const auto& line = world.lines[l];
    std::vector<std::size_t> near;  // elements within 5 cm of the line, whatever their direction
    for (std::size_t i = 0; i < elements.size(); ++i)
      if (segment_distance(elements[i].p0, elements[i].p1, line.p0, line.p1) <= kOnLineM) near.push_back(i);
    double seen = 0, missed = 0, doubled = 0;
    std::uint64_t missed_returns = 0;
    std::map<std::size_t, std::size_t> bins_per_element;
    for (std::size_t b = 0; b < cover[l].size(); ++b) {
      redundant += static_cast<double>(std::max<std::size_t>(1, cover[l][b].size()) - 1) * kBinM;
      doubled += static_cast<double>(std::max<std::size_t>(1, cover[l][b].size()) - 1) * kBinM;
      for (const auto i : cover[l][b]) ++bins_per_element[i];
      if (coverage.hits[l][b] == 0) continue;
      seen += kBinM;
      const Vec c = bin_centre(line.p0, line.p1, b);
      const bool covered = std::any_of(near.begin(), near.end(), [&](std::size_t i) {
        return point_segment_distance(c, elements[i].p0, elements[i].p1) <= kOnLineM;
      });
      const bool short_wall = (line.p1 - line.p0).norm() < kShortestLineM;
      recalled += covered && !short_wall ? kBinM : 0;
      recalled_all += covered ? kBinM : 0;
      score.seen_short_m += short_wall ? kBinM : 0;
      missed += covered ? 0 : kBinM;
      missed_returns += covered ? 0 : coverage.hits[l][b];
    }
    score.seen_length_m += seen;
    if (std::getenv("WM_TRUTH_VERBOSE") && doubled > 0)
      std::fprintf(stderr, "covered twice: %.2f m of the %.2f m wall (%.2f, %.2f) to (%.2f, %.2f)\n", doubled,
                   (line.p1 - line.p0).norm(), line.p0.x(), line.p0.y(), line.p1.x(), line.p1.y());
    if (std::getenv("WM_TRUTH_VERBOSE") && missed > 0)
      std::fprintf(stderr,
                   "not recalled: %.2f of %.2f m seen of the %.2f m wall (%.2f, %.2f) to (%.2f, %.2f), %llu returns\n",
                   missed, seen, (line.p1 - line.p0).norm(), line.p0.x(), line.p0.y(), line.p1.x(), line.p1.y(),
                   static_cast<unsigned long long>(missed_returns));
    if (line.kind != LineKind::table && seen >= 2.0) {
      ++score.walls_seen_2m;
      for (const auto& [i, n] : bins_per_element) walls_elements += n >= 2 ? 1 : 0;
    }
  }
  score.precision = score.element_length_m > 0 ? good / score.element_length_m : 0;
  const double seen_long_m = score.seen_length_m - score.seen_short_m;
  score.recall = seen_long_m > 0 ? recalled / seen_long_m : 0;
  score.recall_all = score.seen_length_m > 0 ? recalled_all / score.seen_length_m : 0;
  score.redundancy = score.element_length_m > 0 ? redundant / score.element_length_m : 0;
  score.elements_per_wall = score.walls_seen_2m > 0 ? walls_elements / static_cast<double>(score.walls_seen_2m) : 0;
  score.people_element_m = people_elements(elements, world);
  return score;
}

AsBuiltScore score_as_built(const ReplayOutcome& outcome, const Building& building, const BuiltWorld& world,
                            const Coverage& coverage) {
  AsBuiltScore score;
  const auto elements = elements_of(*outcome.state);
  const auto& walls = building.walls;

  if (outcome.report) {
    // The bins of each plan wall that a missing or partly_missing verdict covers.
    std::map<std::pair<std::string, std::size_t>, std::size_t> wall_of;
    std::map<std::string, std::vector<std::size_t>> walls_of_object;
    for (std::size_t w = 0; w < walls.size(); ++w) {
      wall_of[{walls[w].object_id, walls[w].edge}] = w;
      walls_of_object[walls[w].object_id].push_back(w);
    }
    std::vector<std::vector<char>> missing(walls.size());
    for (std::size_t w = 0; w < walls.size(); ++w) missing[w].assign(bins_of((walls[w].p1 - walls[w].p0).norm()), 0);
    const auto mark = [&](std::size_t w, double s0, double s1) {
      for (std::size_t b = 0; b < missing[w].size(); ++b) {
        const double centre = (b + 0.5) * kBinM;
        if (centre >= s0 && centre <= s1) missing[w][b] = 1;
      }
    };
    for (const auto& v : outcome.report->verdicts) {
      if (std::getenv("WM_TRUTH_VERBOSE"))
        std::fprintf(stderr, "verdict %s %s: %s\n", v.object_id.c_str(), v.verdict.c_str(), v.explanation.c_str());
      if (v.verdict != "missing" && v.verdict != "partly_missing") continue;
      if (v.edge) {
        const auto it = wall_of.find({v.object_id, *v.edge});
        if (it == wall_of.end()) continue;
        const bool whole = v.verdict == "missing" && v.stretch.s1_m <= v.stretch.s0_m;
        double s0 = whole ? 0 : v.stretch.s0_m, s1 = whole ? 1e9 : v.stretch.s1_m;
        // A stretch runs from the first end of the edge as the server places it, which may be this wall's p1.
        if (!whole) {
          if (const auto* object = outcome.state->find_object(v.object_id);
              object && *v.edge < object->body.edges().size()) {
            const auto edge = object->body.world_edge(*v.edge, Eigen::Matrix2d::Zero());
            const auto& wall = walls[it->second];
            if (std::getenv("WM_TRUTH_DEBUG"))
              std::fprintf(stderr, "DBG %s edge (%.3f,%.3f)-(%.3f,%.3f) wall (%.3f,%.3f)-(%.3f,%.3f) s %.2f %.2f\n",
                           v.object_id.c_str(), edge.p0().x(), edge.p0().y(), edge.p1().x(), edge.p1().y(), wall.p0.x(),
                           wall.p0.y(), wall.p1.x(), wall.p1.y(), s0, s1);
            if ((edge.p0() - wall.p0).norm() > (edge.p0() - wall.p1).norm()) {
              const double length = (wall.p1 - wall.p0).norm();
              std::tie(s0, s1) = std::pair{length - s1, length - s0};
            }
          }
        }
        mark(it->second, s0, s1);
      } else if (const auto it = walls_of_object.find(v.object_id); it != walls_of_object.end()) {
        for (const auto w : it->second) mark(w, 0, 1e9);
      }
    }
    // Demolished walls: the share of what the beams went through that is reported missing, per wall.
    double found = 0;
    std::size_t groups = 0;
    std::vector<char> demolished(walls.size(), 0);
    for (std::size_t g = 0; g < world.demolished.size(); ++g) {
      double through = 0, reported = 0;
      for (std::size_t m = 0; m < world.demolished[g].size(); ++m) {
        const int w = world.demolished[g][m];
        demolished[w] = 1;
        const auto& bins = coverage.seen_through[g][m];
        double wall_through = 0, wall_reported = 0;
        std::string unreported;  // the seen-through bins no verdict covers, as [from, to) m along the wall
        for (std::size_t b = 0; b < bins.size(); ++b) {
          // Beside a surface that still stands (another face of the same wall, a frame left in place) the wall's
          // cells are that surface's: no grid can tell the demolished line from it there, whatever the beams did.
          const Vec centre = bin_centre(walls[w].p0, walls[w].p1, b);
          const bool beside_standing = std::any_of(world.lines.begin(), world.lines.end(), [&](const TrueLine& line) {
            return point_segment_distance(centre, line.p0, line.p1) < kMinDepthBeyondM;
          });
          const bool seen = bins[b] >= kMinBeamsThrough && !beside_standing;
          wall_through += seen ? kBinM : 0;
          wall_reported += seen && missing[w][b] ? kBinM : 0;
          if (seen && !missing[w][b])
            unreported += " " + fixed(static_cast<double>(b) * kBinM, 2) + "(" + std::to_string(bins[b]) + ")";
        }
        through += wall_through;
        reported += wall_reported;
        if (std::getenv("WM_TRUTH_VERBOSE"))
          std::fprintf(
              stderr,
              "demolished %s/%zu (%.2f m, (%.2f, %.2f) to (%.2f, %.2f)): seen through %.2f m, reported missing "
              "%.2f m; not reported at m (beams):%s\n",
              walls[w].object_id.c_str(), walls[w].edge, (walls[w].p1 - walls[w].p0).norm(), walls[w].p0.x(),
              walls[w].p0.y(), walls[w].p1.x(), walls[w].p1.y(), wall_through, wall_reported, unreported.c_str());
      }
      if (through > 0) {
        found += reported / through;
        ++groups;
      }
    }
    if (groups > 0) score.demolished_found = found / static_cast<double>(groups);
    // Existing walls in view: every wall of the plan still standing that some beam returned from.
    double in_view = 0, reported = 0, near_people = 0;
    for (std::size_t l = 0; l < world.lines.size(); ++l) {
      const int w = world.lines[l].plan_wall;
      if (w < 0) continue;
      const auto& hits = coverage.hits[l];
      if (std::none_of(hits.begin(), hits.end(), [](std::uint32_t n) { return n > 0; })) continue;
      in_view += (walls[w].p1 - walls[w].p0).norm();
      if (std::getenv("WM_TRUTH_VERBOSE") &&
          std::any_of(missing[w].begin(), missing[w].end(), [](char m) { return m != 0; }))
        std::fprintf(stderr, "false missing: %s/%zu (%.2f m) from (%.2f, %.2f) to (%.2f, %.2f)\n",
                     walls[w].object_id.c_str(), walls[w].edge, (walls[w].p1 - walls[w].p0).norm(), walls[w].p0.x(),
                     walls[w].p0.y(), walls[w].p1.x(), walls[w].p1.y());
      for (std::size_t b = 0; b < missing[w].size(); ++b) {
        if (!missing[w][b]) continue;
        reported += kBinM;
        const Vec c = bin_centre(walls[w].p0, walls[w].p1, b);
        // Tracks keep 0.45 m from every line, so a wall a person walked past is within 1 m of the track.
        for (const auto& person : world.people)
          if (point_segment_distance(c, person.a, person.b) <= 1.0) {
            near_people += kBinM;
            break;
          }
      }
    }
    score.false_missing = in_view > 0 ? reported / in_view : 0;
    score.people_missing_m = near_people;
  }

  // New partitions: the share of their seen length (bins with at least kMinReturnsSeen returns) that elements on them
  // (within 5 cm and 3°) cover, a bin where its centre is within 5 cm of one: as the mapping recall asks, and a short
  // last bin needs no element sample on it.
  double found_new = 0;
  std::size_t partitions_seen = 0;
  for (const int p : world.partitions) {
    const auto& line = world.lines[static_cast<std::size_t>(p)];
    std::vector<std::size_t> on;
    for (std::size_t i = 0; i < elements.size(); ++i)
      if (on_line(elements[i], line)) on.push_back(i);
    double seen = 0, covered = 0;
    std::vector<bool> missed(coverage.hits[p].size(), false);
    for (std::size_t b = 0; b < coverage.hits[p].size(); ++b) {
      if (coverage.hits[p][b] < kMinReturnsSeen) continue;
      seen += kBinM;
      const Vec c = bin_centre(line.p0, line.p1, b);
      const bool covered_here = std::any_of(on.begin(), on.end(), [&](std::size_t i) {
        return point_segment_distance(c, elements[i].p0, elements[i].p1) <= kOnLineM;
      });
      covered += covered_here ? kBinM : 0;
      missed[b] = !covered_here;
    }
    if (seen > 0) {
      found_new += covered / seen;
      ++partitions_seen;
    }
    if (std::getenv("WM_TRUTH_VERBOSE")) {
      std::fprintf(stderr,
                   "partition (%.2f, %.2f) to (%.2f, %.2f): %.2f m seen, %.2f m covered; uncovered bins:", line.p0.x(),
                   line.p0.y(), line.p1.x(), line.p1.y(), seen, covered);
      for (std::size_t b = 0; b < missed.size(); ++b)
        if (missed[b]) std::fprintf(stderr, " %zu(%u)", b, coverage.hits[p][b]);
      std::fprintf(stderr, "\n");
    }
  }
  score.new_found = partitions_seen > 0 ? found_new / static_cast<double>(partitions_seen) : 0;

  // The table: where the plan object ended, and elements made of its sides instead.
  score.table_removed = !world.table;
  if (world.table) {
    if (const auto* table = outcome.state->find_object(kTableId)) {
      const auto& pose = table->body.pose();
      score.table_error_m = std::hypot(pose.x_m - world.table->x_m, pose.y_m - world.table->y_m);
      score.table_error_deg =
          std::abs(std::remainder(pose.theta_rad - world.table->theta_rad, 2 * std::numbers::pi)) / kDeg;
    }
    const auto sides = table_sides(*world.table);
    for (const auto& e : elements) {
      std::size_t near = 0;
      for (std::size_t k = 0; k < e.samples(); ++k) {
        const Vec p = e.sample(k);
        for (const auto& [a, b] : sides)
          if (point_segment_distance(p, a, b) <= 0.10) {
            ++near;
            break;
          }
      }
      score.table_edge_elements += 2 * near >= e.samples() ? 1 : 0;
      if (std::getenv("WM_TRUTH_VERBOSE") && 2 * near >= e.samples())
        std::fprintf(stderr, "table side as an element: (%.2f, %.2f) to (%.2f, %.2f)\n", e.p0.x(), e.p0.y(), e.p1.x(),
                     e.p1.y());
    }
    if (std::getenv("WM_TRUTH_VERBOSE"))
      std::fprintf(stderr, "table: drawn at (%.2f, %.2f, %.1f deg), stands at (%.2f, %.2f, %.1f deg)\n",
                   building.table.x_m, building.table.y_m, building.table.theta_rad / kDeg, world.table->x_m,
                   world.table->y_m, world.table->theta_rad / kDeg);
  }
  score.people_element_m = people_elements(elements, world);
  return score;
}

TruthResult run_truth(const std::string& name, const TruthOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  TruthResult result;
  result.building = name;
  result.pose_noise = options.pose_noise;
  const Building building = load_building(name, options.data_dir, options.seed, options.max_route_m);
  const BuiltWorld world = build_world(building, options.edits, options.seed);
  LaserOptions laser = options.laser;
  const bool low = options.pose_noise == PoseNoise::low;
  laser.sigma_xy_m = low ? 0.01 : 0.03;
  laser.sigma_theta_rad = (low ? 0.2 : 0.5) * kDeg;
  const Drive drove = drive(building, world, laser, options.seed);
  result.scans = drove.scans.size();
  result.route_m = drove.route_m;
  // The covariance a robot's localisation would post with the pose it believes.
  const Eigen::Matrix3d pose_cov =
      Eigen::Vector3d(laser.sigma_xy_m * laser.sigma_xy_m, laser.sigma_xy_m * laser.sigma_xy_m,
                      laser.sigma_theta_rad * laser.sigma_theta_rad)
          .asDiagonal();
  const auto mapped = replay_scans(drove.scans, pose_cov, std::nullopt, options);
  if (std::getenv("WM_TRUTH_VERBOSE")) print_alignment(drove, mapped);
  result.mapping = score_mapping(*mapped.state, world, drove.coverage);
  if (options.with_plan) {
    const auto planned = replay_scans(drove.scans, pose_cov, building.plan, options);
    result.as_built = score_as_built(planned, building, world, drove.coverage);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string format_table(const std::vector<TruthResult>& results) {
  std::ostringstream out;
  char line[512];
  const char* header = "%-11s %-5s %6s %7s %9s %7s %10s %10s %8s %10s %10s %9s %15s %8s %20s\n";
  std::snprintf(line, sizeof line, header, "building", "noise", "scans", "route_m", "precision", "recall", "recall_all",
                "redundancy", "el/wall", "demolished", "false_miss", "new_found", "table_cm,deg", "table_el",
                "people_m el/el/miss");
  out << line;
  MappingScore worst_map{1, 1, 1, 0, 0};
  std::optional<double> worst_demolished, worst_false, worst_people_missing;
  double worst_new = 1, worst_table_cm = 0, worst_table_deg = 0, worst_people = 0;
  std::size_t worst_table_el = 0;
  bool any_plan = false;
  const auto lower = [](std::optional<double>& w, const std::optional<double>& v) {
    if (v && (!w || *v < *w)) w = v;
  };
  const auto higher = [](std::optional<double>& w, const std::optional<double>& v) {
    if (v && (!w || *v > *w)) w = v;
  };
  for (const auto& r : results) {
    const auto& m = r.mapping;
    worst_map.precision = std::min(worst_map.precision, m.precision);
    worst_map.recall = std::min(worst_map.recall, m.recall);
    worst_map.recall_all = std::min(worst_map.recall_all, m.recall_all);
    worst_map.redundancy = std::max(worst_map.redundancy, m.redundancy);
    worst_map.elements_per_wall = std::max(worst_map.elements_per_wall, m.elements_per_wall);
    worst_people = std::max(worst_people, m.people_element_m);
    std::string demolished = "-", false_missing = "-", new_found = "-", table = "-", table_el = "-",
                people = fixed(m.people_element_m, 2);
    if (r.as_built) {
      const auto& a = *r.as_built;
      any_plan = true;
      demolished = optional_fixed(a.demolished_found, 3);
      false_missing = optional_fixed(a.false_missing, 3);
      new_found = fixed(a.new_found, 3);
      table = a.table_removed ? "removed" : fixed(100 * a.table_error_m, 1) + "," + fixed(a.table_error_deg, 1);
      table_el = a.table_removed ? "-" : std::to_string(a.table_edge_elements);
      people += "/" + fixed(a.people_element_m, 2) + "/" + optional_fixed(a.people_missing_m, 2);
      lower(worst_demolished, a.demolished_found);
      higher(worst_false, a.false_missing);
      higher(worst_people_missing, a.people_missing_m);
      worst_new = std::min(worst_new, a.new_found);
      if (!a.table_removed) {
        worst_table_cm = std::max(worst_table_cm, 100 * a.table_error_m);
        worst_table_deg = std::max(worst_table_deg, a.table_error_deg);
        worst_table_el = std::max(worst_table_el, a.table_edge_elements);
      }
      worst_people = std::max(worst_people, a.people_element_m);
    }
    std::snprintf(line, sizeof line, header, r.building.c_str(), pose_noise_name(r.pose_noise),
                  std::to_string(r.scans).c_str(), fixed(r.route_m, 0).c_str(), fixed(m.precision, 3).c_str(),
                  fixed(m.recall, 3).c_str(), fixed(m.recall_all, 3).c_str(), fixed(m.redundancy, 3).c_str(),
                  fixed(m.elements_per_wall, 2).c_str(), demolished.c_str(), false_missing.c_str(), new_found.c_str(),
                  table.c_str(), table_el.c_str(), people.c_str());
    out << line;
  }
  if (!results.empty()) {
    std::snprintf(line, sizeof line, header, "worst", "", "", "", fixed(worst_map.precision, 3).c_str(),
                  fixed(worst_map.recall, 3).c_str(), fixed(worst_map.recall_all, 3).c_str(),
                  fixed(worst_map.redundancy, 3).c_str(), fixed(worst_map.elements_per_wall, 2).c_str(),
                  any_plan ? optional_fixed(worst_demolished, 3).c_str() : "-",
                  any_plan ? optional_fixed(worst_false, 3).c_str() : "-", any_plan ? fixed(worst_new, 3).c_str() : "-",
                  any_plan ? (fixed(worst_table_cm, 1) + "," + fixed(worst_table_deg, 1)).c_str() : "-",
                  any_plan ? std::to_string(worst_table_el).c_str() : "-",
                  (fixed(worst_people, 2) + " el, " + optional_fixed(worst_people_missing, 2) + " miss").c_str());
    out << line;
  }
  return out.str();
}

}  // namespace wm::truth
