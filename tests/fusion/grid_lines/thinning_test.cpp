#include "fusion/grid_lines/thinning.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace wm::fusion {
namespace {

// A binary test image written top row first ('#' foreground), stored bottom row first like a raster.
struct Image {
  std::int64_t width = 0;
  std::int64_t height = 0;
  std::vector<std::uint8_t> pixels;

  std::uint8_t at(std::int64_t x, std::int64_t y) const {
    if (x < 0 || y < 0 || x >= width || y >= height) return 0;
    return pixels[static_cast<std::size_t>(y * width + x)];
  }
  std::uint8_t& at(std::int64_t x, std::int64_t y) { return pixels[static_cast<std::size_t>(y * width + x)]; }
};

Image parse(const std::vector<std::string>& rows) {
  Image img{static_cast<std::int64_t>(rows[0].size()), static_cast<std::int64_t>(rows.size()), {}};
  img.pixels.assign(static_cast<std::size_t>(img.width * img.height), 0);
  for (std::int64_t r = 0; r < img.height; ++r) {
    for (std::int64_t x = 0; x < img.width; ++x) {
      img.at(x, img.height - 1 - r) = rows[static_cast<std::size_t>(r)][static_cast<std::size_t>(x)] == '#' ? 1 : 0;
    }
  }
  return img;
}

Image blank(std::int64_t width, std::int64_t height) {
  return {width, height, std::vector<std::uint8_t>(static_cast<std::size_t>(width * height), 0)};
}

Image thin(const Image& img) { return {img.width, img.height, zhang_suen_thinning(img.pixels, img.width, img.height)}; }

std::size_t count(const Image& img) {
  std::size_t n = 0;
  for (auto v : img.pixels) n += v != 0 ? 1 : 0;
  return n;
}

// Connected components of the pixels equal to `value`, 8- or 4-connected; the background (value 0) is taken as
// extending beyond the border, so the outside counts as one component.
int components(const Image& img, std::uint8_t value, bool eight) {
  const std::int64_t w = img.width + 2, h = img.height + 2;
  std::vector<int> label(static_cast<std::size_t>(w * h), 0);
  auto value_at = [&](std::int64_t x, std::int64_t y) { return img.at(x - 1, y - 1) != 0 ? 1 : 0; };
  int n = 0;
  for (std::int64_t y0 = 0; y0 < h; ++y0) {
    for (std::int64_t x0 = 0; x0 < w; ++x0) {
      if (value_at(x0, y0) != value || label[static_cast<std::size_t>(y0 * w + x0)] != 0) continue;
      ++n;
      std::vector<std::pair<std::int64_t, std::int64_t>> stack{{x0, y0}};
      label[static_cast<std::size_t>(y0 * w + x0)] = n;
      while (!stack.empty()) {
        const auto [x, y] = stack.back();
        stack.pop_back();
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            if ((dx == 0 && dy == 0) || (!eight && dx != 0 && dy != 0)) continue;
            const std::int64_t nx = x + dx, ny = y + dy;
            if (nx < 0 || ny < 0 || nx >= w || ny >= h || value_at(nx, ny) != value) continue;
            int& l = label[static_cast<std::size_t>(ny * w + nx)];
            if (l != 0) continue;
            l = n;
            stack.emplace_back(nx, ny);
          }
        }
      }
    }
  }
  return n;
}

// True when no 2×2 block is entirely foreground (a one-pixel-wide result has none).
bool has_no_2x2_block(const Image& img) {
  for (std::int64_t y = 0; y + 1 < img.height; ++y) {
    for (std::int64_t x = 0; x + 1 < img.width; ++x) {
      if (img.at(x, y) && img.at(x + 1, y) && img.at(x, y + 1) && img.at(x + 1, y + 1)) return false;
    }
  }
  return true;
}

bool subset(const Image& a, const Image& b) {
  for (std::size_t i = 0; i < a.pixels.size(); ++i) {
    if (a.pixels[i] != 0 && b.pixels[i] == 0) return false;
  }
  return true;
}

TEST(ThinningTest, ThickBarBecomesAOnePixelLineAlongItsMiddle) {
  Image img = blank(50, 15);
  for (std::int64_t y = 5; y < 10; ++y) {
    for (std::int64_t x = 5; x < 45; ++x) img.at(x, y) = 1;
  }
  const Image skeleton = thin(img);
  // Away from the ends, each column holds exactly one pixel, on the bar's middle row.
  for (std::int64_t x = 8; x < 42; ++x) {
    int in_column = 0;
    for (std::int64_t y = 0; y < img.height; ++y) in_column += skeleton.at(x, y);
    EXPECT_EQ(in_column, 1) << "column " << x;
    EXPECT_EQ(skeleton.at(x, 7), 1) << "column " << x;
  }
  EXPECT_EQ(components(skeleton, 1, true), 1);
  EXPECT_TRUE(has_no_2x2_block(skeleton));
  EXPECT_TRUE(subset(skeleton, img));
}

TEST(ThinningTest, ThickRingStaysAClosedLoopAroundItsHole) {
  Image img = blank(40, 40);
  for (std::int64_t y = 0; y < 40; ++y) {
    for (std::int64_t x = 0; x < 40; ++x) {
      const double r = std::hypot(x - 19.5, y - 19.5);
      img.at(x, y) = r >= 9.0 && r <= 14.0 ? 1 : 0;
    }
  }
  const Image skeleton = thin(img);
  EXPECT_EQ(components(skeleton, 1, true), 1);
  EXPECT_EQ(components(skeleton, 0, false), 2);  // outside and the hole
  EXPECT_TRUE(has_no_2x2_block(skeleton));
  EXPECT_LT(count(skeleton), count(img) / 3);
}

TEST(ThinningTest, TwoByTwoBlockShrinksToAConnectedPairInsteadOfVanishing) {
  // Plain Zhang–Suen deletes all four pixels in its first sub-iteration.
  const Image skeleton = thin(parse({"....", ".##.", ".##.", "...."}));
  EXPECT_EQ(count(skeleton), 2u);
  EXPECT_EQ(components(skeleton, 1, true), 1);
}

TEST(ThinningTest, TwoPixelDiagonalStrokeKeepsItsConnectivity) {
  Image img = blank(30, 30);
  for (std::int64_t i = 2; i < 27; ++i) {
    img.at(i, i) = 1;
    img.at(i + 1, i) = 1;
  }
  const Image skeleton = thin(img);
  EXPECT_EQ(components(skeleton, 1, true), 1);
  EXPECT_GE(count(skeleton), 25u);  // still spans the stroke
  EXPECT_TRUE(has_no_2x2_block(skeleton));
}

TEST(ThinningTest, OnePixelShapesAreAlreadySkeletons) {
  const Image img = parse({".........", ".#.......", "...#####.", "...#.....", "...#...#.", "....#....", "........."});
  EXPECT_EQ(thin(img).pixels, img.pixels);
}

TEST(ThinningTest, ThinsBlobsTouchingTheImageBorder) {
  Image img = blank(20, 4);
  for (auto& v : img.pixels) v = 1;  // the whole image is foreground
  const Image skeleton = thin(img);
  EXPECT_EQ(components(skeleton, 1, true), 1);
  EXPECT_TRUE(has_no_2x2_block(skeleton));
  EXPECT_GE(count(skeleton), 14u);
  EXPECT_LE(count(skeleton), 22u);
}

TEST(ThinningTest, KnownSmallCase) {
  // A 3-pixel-thick horizontal bar thins to its middle row. Plain Zhang–Suen gives columns 2..7; with the Lü–Wang
  // end condition (B >= 3) one end keeps the pixel next to it, so columns 1..7 or 2..8 are also right.
  const Image skeleton = thin(parse({"..........", ".########.", ".########.", ".########.", ".........."}));
  const Image plain = parse({"..........", "..........", "..######..", "..........", ".........."});
  const Image longer_left = parse({"..........", "..........", ".#######..", "..........", ".........."});
  const Image longer_right = parse({"..........", "..........", "..#######.", "..........", ".........."});
  EXPECT_TRUE(skeleton.pixels == plain.pixels || skeleton.pixels == longer_left.pixels ||
              skeleton.pixels == longer_right.pixels);
}

TEST(ThinningTest, RandomBlobsKeepTheirTopologyAndEndThin) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 30; ++trial) {
    Image img = blank(48, 40);
    std::uniform_int_distribution<std::int64_t> x(0, 47), y(0, 39), size(1, 9);
    for (int k = 0; k < 12; ++k) {  // overlapping rectangles and discs
      const std::int64_t cx = x(rng), cy = y(rng), s = size(rng);
      const bool disc = (k % 2) == 0;
      for (std::int64_t yy = std::max<std::int64_t>(0, cy - s); yy < std::min<std::int64_t>(40, cy + s); ++yy) {
        for (std::int64_t xx = std::max<std::int64_t>(0, cx - s); xx < std::min<std::int64_t>(48, cx + s); ++xx) {
          if (!disc || std::hypot(xx - cx, yy - cy) <= s) img.at(xx, yy) = 1;
        }
      }
    }
    const Image skeleton = thin(img);
    SCOPED_TRACE(trial);
    EXPECT_TRUE(subset(skeleton, img));
    EXPECT_EQ(components(skeleton, 1, true), components(img, 1, true));
    EXPECT_EQ(components(skeleton, 0, false), components(img, 0, false));
    // Thin: a second pass changes nothing.
    EXPECT_EQ(thin(skeleton).pixels, skeleton.pixels);
  }
}

TEST(ThinningTest, EmptyImageStaysEmptyAndBadSizesThrow) {
  EXPECT_EQ(count(thin(blank(5, 3))), 0u);
  const std::vector<std::uint8_t> px(6, 1);
  EXPECT_THROW(zhang_suen_thinning(px, 4, 2), std::invalid_argument);
  EXPECT_THROW(zhang_suen_thinning(px, 0, 6), std::invalid_argument);
  EXPECT_THROW(zhang_suen_thinning(px, 6, -1), std::invalid_argument);
}

TEST(ThresholdTest, MarksKnownCellsAtOrAboveThePOccupiedOnly) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const ProbabilityRaster raster{GridGeometry({0, 0}, 0.05, 3, 2), {0.1f, 0.65f, 0.649f, nan, 1.0f, 0.0f}};
  EXPECT_EQ(threshold(raster, 0.65f), (std::vector<std::uint8_t>{0, 1, 0, 0, 1, 0}));
  EXPECT_THROW(threshold(raster, 0.0f), std::invalid_argument);
  EXPECT_THROW(threshold(raster, 1.5f), std::invalid_argument);
  const ProbabilityRaster short_raster{GridGeometry({0, 0}, 0.05, 3, 2), {0.1f}};
  EXPECT_THROW(threshold(short_raster, 0.5f), std::invalid_argument);
  const ProbabilityRaster bad_value{GridGeometry({0, 0}, 0.05, 1, 1), {1.5f}};
  EXPECT_THROW(threshold(bad_value, 0.5f), std::invalid_argument);
}

}  // namespace
}  // namespace wm::fusion
