#include "server/formats/map_server.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace wm::formats {

std::string pgm_image(const std::vector<float>& values, const fusion::GridGeometry& region) {
  const auto width = region.width(), height = region.height();
  if (static_cast<std::int64_t>(values.size()) != width * height)
    throw std::invalid_argument("pgm_image: " + std::to_string(values.size()) + " values for " +
                                std::to_string(width * height) + " cells");
  std::ostringstream head;
  head.precision(10);
  head << "P5\n# worldmodel occupancy grid; origin " << region.origin_m().x() << " " << region.origin_m().y()
       << " resolution " << region.resolution_m() << "\n"
       << width << " " << height << "\n255\n";
  std::string out = head.str();
  const auto header = out.size();
  out.resize(header + static_cast<std::size_t>(width * height));
  for (std::int64_t row = 0; row < height; ++row) {
    const float* src = values.data() + (height - 1 - row) * width;
    char* dst = out.data() + header + row * width;
    for (std::int64_t x = 0; x < width; ++x) {
      const float p = src[x];
      dst[x] = static_cast<char>(
          std::isnan(p) ? kUnknownPixel : static_cast<int>(std::lround(255.0 * (1.0 - std::clamp(p, 0.0f, 1.0f)))));
    }
  }
  return out;
}

std::string map_yaml(const fusion::GridGeometry& region) {
  std::ostringstream yaml;
  yaml.precision(10);
  yaml << "image: map.pgm\n"
       << "mode: trinary\n"
       << "resolution: " << region.resolution_m() << "\n"
       << "origin: [" << region.origin_m().x() << ", " << region.origin_m().y() << ", 0.0]\n"
       << "negate: 0\n"
       << "occupied_thresh: " << kOccupiedThreshold << "\n"
       << "free_thresh: " << kFreeThreshold << "\n";
  return yaml.str();
}

}  // namespace wm::formats
