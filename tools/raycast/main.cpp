// wm-raycast-log: a robot's drive through a floor plan as a CARMEN log (ROBOTLASER1, a 360° laser ray-cast against
// every line of an AMRL vector map, σ 1 cm), for trying the server on a building without a real log of it. With
// --frame the poses are written in the frame of a robot that started elsewhere (its map is not the plan's frame):
// what `wmctl floorplan align` is for.
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <numbers>
#include <sstream>
#include <string>

#include "common/parse_number.h"
#include "tools/raycast/raycast.h"

namespace {

const char* kUsage =
    "usage: wm-raycast-log MAP.vectormap.json OUT.log [--route gdc1|\"x,y x,y ...\"] [--frame DX,DY,DTHETA_DEG]\n"
    "                      [--step M] [--beams N] [--range M]\n"
    "  --route  the polyline driven (default gdc1: GDC1's navigation graph)\n"
    "  --frame  where the plan's frame is in the robot's frame: poses are written as frame * pose\n";

std::vector<double> numbers(const std::string& text, char separator) {
  std::vector<double> values;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, separator);) values.push_back(std::stod(item));
  return values;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace wm;
  if (argc < 3) {
    std::cerr << kUsage;
    return 2;
  }
  try {
    const auto lines = raycast::read_vectormap(argv[1]);
    auto route = raycast::gdc1_route();
    raycast::DriveOptions options;
    double dx = 0, dy = 0, dtheta = 0;
    for (int i = 3; i + 1 < argc; i += 2) {
      const std::string flag = argv[i], value = argv[i + 1];
      if (flag == "--route" && value != "gdc1") {
        std::vector<Eigen::Vector2d> polyline;
        std::stringstream in(value);
        for (std::string point; in >> point;) {
          const auto xy = numbers(point, ',');
          if (xy.size() != 2) throw std::invalid_argument("--route: expected x,y points");
          polyline.emplace_back(xy[0], xy[1]);
        }
        route = {polyline};
      } else if (flag == "--frame") {
        const auto f = numbers(value, ',');
        if (f.size() != 3) throw std::invalid_argument("--frame: expected DX,DY,DTHETA_DEG");
        dx = f[0];
        dy = f[1];
        dtheta = f[2] * std::numbers::pi / 180;
      } else if (flag == "--step") {
        options.step_m = wm::parse_number<double>(flag, value, 0.001, 100);
      } else if (flag == "--beams") {
        options.beams = wm::parse_number<int>(flag, value, 2, 100'000);
      } else if (flag == "--range") {
        options.max_range_m = wm::parse_number<double>(flag, value, 0.1, 1000);
      } else if (flag != "--route") {
        throw std::invalid_argument("unknown flag " + flag);
      }
    }
    std::ofstream out(argv[2]);
    if (!out) throw std::runtime_error(std::string("cannot write ") + argv[2]);
    out.precision(9);
    double stamp = 0;
    const Eigen::Rotation2Dd turn(dtheta);
    const auto scans = raycast::simulate_scans(lines, route, options);
    for (const auto& scan : scans) {
      const Eigen::Vector2d p =
          turn * Eigen::Vector2d(scan.sensor_pose.x_m, scan.sensor_pose.y_m) + Eigen::Vector2d(dx, dy);
      const double theta = scan.sensor_pose.theta_rad + dtheta;
      out << "ROBOTLASER1 0 " << scan.angle_min_rad << ' ' << scan.angle_increment_rad * scan.ranges_m.size() << ' '
          << scan.angle_increment_rad << ' ' << scan.range_max_m << " 0.01 0 " << scan.ranges_m.size();
      for (const double r : scan.ranges_m) out << ' ' << r;
      out << " 0 " << p.x() << ' ' << p.y() << ' ' << theta << ' ' << p.x() << ' ' << p.y() << ' ' << theta
          << " 0 0 0 0 0 " << stamp << " raycast " << stamp << "\n";
      stamp += 0.1;
    }
    std::cerr << "wm-raycast-log: " << scans.size() << " scans of " << options.beams << " beams against "
              << lines.size() << " lines -> " << argv[2] << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "wm-raycast-log: " << e.what() << "\n" << kUsage;
    return 2;
  }
}
