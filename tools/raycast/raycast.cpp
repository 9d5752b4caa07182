#include "tools/raycast/raycast.h"

#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <random>
#include <regex>
#include <sstream>
#include <stdexcept>

namespace wm::raycast {

std::vector<PlanLine> read_vectormap(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  static const std::regex number(R"("[xy]"\s*:\s*(-?[0-9.eE+-]+))");
  std::vector<double> values;
  for (auto it = std::sregex_iterator(s.begin(), s.end(), number); it != std::sregex_iterator(); ++it)
    values.push_back(std::stod((*it)[1].str()));
  if (values.size() % 4 != 0 || values.empty()) throw std::runtime_error("not an AMRL vector map: " + path);
  std::vector<PlanLine> lines;
  for (std::size_t i = 0; i < values.size(); i += 4)
    lines.push_back({{values[i], values[i + 1]}, {values[i + 2], values[i + 3]}});
  return lines;
}

double cast_ray(const std::vector<PlanLine>& lines, const Eigen::Vector2d& origin, const Eigen::Vector2d& dir,
                double max_range) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& l : lines) {
    const Eigen::Vector2d e = l.p1 - l.p0;
    const double denom = dir.x() * e.y() - dir.y() * e.x();
    if (std::abs(denom) < 1e-12) continue;
    const Eigen::Vector2d w = l.p0 - origin;
    const double t = (w.x() * e.y() - w.y() * e.x()) / denom;
    const double u = (w.x() * dir.y() - w.y() * dir.x()) / denom;
    if (t > 1e-9 && t < max_range && u >= 0 && u <= 1) best = std::min(best, t);
  }
  return best;
}

std::vector<std::vector<Eigen::Vector2d>> gdc1_route() {
  const Eigen::Vector2d n0(-26.637, 19.653), n1(-33.531, 20.101), n2(-26.597, 8.607), n3(34.262, 8.839),
      n4(-13.638, 8.459), n5(-10.101, 8.431), n6(-10.239, 3.651), n7(-13.638, 3.706), n8(-13.744, 13.082);
  return {{n1, n0, n2, n4, n5, n3}, {n4, n7}, {n4, n8}, {n5, n6}};
}

std::vector<fusion::LaserScan> simulate_scans(const std::vector<PlanLine>& lines,
                                              const std::vector<std::vector<Eigen::Vector2d>>& route,
                                              const DriveOptions& options) {
  std::mt19937 rng(options.seed);
  std::normal_distribution<double> noise(0.0, options.sigma_range_m);
  std::vector<fusion::LaserScan> scans;
  for (const auto& polyline : route)
    for (std::size_t k = 0; k + 1 < polyline.size(); ++k) {
      const Eigen::Vector2d a = polyline[k], b = polyline[k + 1];
      const int steps = std::max(1, static_cast<int>((b - a).norm() / options.step_m));
      const double heading = std::atan2((b - a).y(), (b - a).x());
      for (int s = 0; s <= steps; ++s) {
        const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(s) / steps);
        fusion::LaserScan scan;
        scan.sensor_pose = {p.x(), p.y(), heading};
        scan.angle_min_rad = -std::numbers::pi;
        scan.angle_increment_rad = 2 * std::numbers::pi / options.beams;
        scan.range_min_m = 0.05;
        scan.range_max_m = options.max_range_m;
        scan.sigma_range_m = options.sigma_range_m;
        for (int i = 0; i < options.beams; ++i) {
          const double angle = heading + scan.angle_min_rad + scan.angle_increment_rad * i;
          const double r = cast_ray(lines, p, {std::cos(angle), std::sin(angle)}, options.max_range_m);
          scan.ranges_m.push_back(std::isfinite(r) ? r + noise(rng) : options.max_range_m);
        }
        scans.push_back(std::move(scan));
      }
    }
  return scans;
}

}  // namespace wm::raycast
