#include "fusion/grid_lines/thinning.h"

#include <array>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace wm::fusion {
namespace {

// The 8-neighbourhood as a byte, in Zhang & Suen's order starting north and turning clockwise:
// bit 0 P2 (N), 1 P3 (NE), 2 P4 (E), 3 P5 (SE), 4 P6 (S), 5 P7 (SW), 6 P8 (W), 7 P9 (NW). Rows grow upwards
// (row-major from the lower-left cell), so north is +1 row; the algorithm is symmetric, only the naming follows.
constexpr bool bit(unsigned code, int i) { return ((code >> i) & 1u) != 0; }

// Zhang–Suen deletion tables, index = neighbourhood code; [0] first sub-iteration, [1] second.
constexpr std::array<std::array<bool, 256>, 2> make_zhang_suen_tables() {
  std::array<std::array<bool, 256>, 2> tables{};
  for (unsigned code = 0; code < 256; ++code) {
    const int b = std::popcount(code);
    int a = 0;  // 0→1 transitions in P2, P3, ..., P9, P2
    for (int i = 0; i < 8; ++i) a += (!bit(code, i) && bit(code, (i + 1) % 8)) ? 1 : 0;
    // Lü & Wang (CACM 29(3), 1986): B >= 3 instead of 2, so the end of a 2-pixel-wide diagonal stroke (B = 2,
    // its neighbours adjacent) is not eaten away pass after pass until the stroke is gone.
    const bool base = b >= 3 && b <= 6 && a == 1;
    const bool p2 = bit(code, 0), p4 = bit(code, 2), p6 = bit(code, 4), p8 = bit(code, 6);
    tables[0][code] = base && !(p2 && p4 && p6) && !(p4 && p6 && p8);
    tables[1][code] = base && !(p2 && p4 && p8) && !(p2 && p6 && p8);
  }
  return tables;
}

// Yokoi's 8-connectivity number N8 = Σ_{k = 1, 3, 5, 7} (x̄_k − x̄_k·x̄_{k+1}·x̄_{k+2}) over the complemented
// neighbours x_1 = E, x_2 = NE, x_3 = N, ... x_8 = SE (counter-clockwise from east), x_9 = x_1. A foreground pixel
// is 8-simple (deleting it changes neither the 8-connected foreground nor the 4-connected background) iff N8 = 1.
constexpr std::array<bool, 256> make_simple_table() {
  std::array<bool, 256> table{};
  // Zhang–Suen bit of x_1..x_8: E 2, NE 1, N 0, NW 7, W 6, SW 5, S 4, SE 3.
  constexpr std::array<int, 8> kBitOf = {2, 1, 0, 7, 6, 5, 4, 3};
  for (unsigned code = 0; code < 256; ++code) {
    auto complement = [&](int k) { return bit(code, kBitOf[static_cast<std::size_t>(k % 8)]) ? 0 : 1; };
    int n8 = 0;
    for (int k = 0; k < 8; k += 2) n8 += complement(k) - complement(k) * complement(k + 1) * complement(k + 2);
    table[code] = n8 == 1;
  }
  return table;
}

constexpr auto kZhangSuen = make_zhang_suen_tables();
constexpr auto kSimple = make_simple_table();

[[noreturn]] void fail(const char* function, const std::string& message) {
  throw std::invalid_argument(std::string(function) + ": " + message);
}

// The binary image padded by one 0 pixel on every side, so that neighbour access needs no bounds checks.
class PaddedImage {
 public:
  PaddedImage(std::span<const std::uint8_t> image, std::int64_t width, std::int64_t height)
      : width_(width),
        height_(height),
        stride_(static_cast<std::int32_t>(width + 2)),
        pixels_(static_cast<std::size_t>((width + 2) * (height + 2)), 0) {
    for (std::int64_t y = 0; y < height; ++y) {
      for (std::int64_t x = 0; x < width; ++x) {
        pixels_[static_cast<std::size_t>(index(x, y))] = image[static_cast<std::size_t>(y * width + x)] != 0 ? 1 : 0;
      }
    }
    offsets_ = {stride_, stride_ + 1, 1, 1 - stride_, -stride_, -stride_ - 1, -1, stride_ - 1};
  }

  std::int32_t index(std::int64_t x, std::int64_t y) const {
    return static_cast<std::int32_t>((y + 1) * stride_ + x + 1);
  }
  bool at(std::int32_t i) const { return pixels_[static_cast<std::size_t>(i)] != 0; }
  void clear(std::int32_t i) { pixels_[static_cast<std::size_t>(i)] = 0; }
  std::int32_t neighbour(std::int32_t i, int k) const { return i + offsets_[static_cast<std::size_t>(k)]; }

  unsigned code(std::int32_t i) const {
    unsigned c = 0;
    for (int k = 0; k < 8; ++k) c |= static_cast<unsigned>(pixels_[static_cast<std::size_t>(i + offsets_[k])]) << k;
    return c;
  }

  std::vector<std::uint8_t> unpadded() const {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(width_ * height_));
    for (std::int64_t y = 0; y < height_; ++y) {
      for (std::int64_t x = 0; x < width_; ++x) {
        out[static_cast<std::size_t>(y * width_ + x)] = pixels_[static_cast<std::size_t>(index(x, y))];
      }
    }
    return out;
  }

 private:
  std::int64_t width_;
  std::int64_t height_;
  std::int32_t stride_;
  std::vector<std::uint8_t> pixels_;
  std::array<std::int32_t, 8> offsets_{};
};

void check_size(const char* caller, std::size_t size, std::int64_t width, std::int64_t height) {
  if (width < 1 || height < 1) {
    fail(caller, "width and height must be >= 1, got " + std::to_string(width) + " x " + std::to_string(height));
  }
  if (width > kMaxRasterCells || height > kMaxRasterCells || width * height > kMaxRasterCells) {
    fail(caller, "more than 2^28 pixels");
  }
  if (static_cast<std::int64_t>(size) != width * height) {
    fail(caller, "image has " + std::to_string(size) + " pixels, expected " + std::to_string(width * height));
  }
}

}  // namespace

void fill_small_holes(std::span<std::uint8_t> image, std::int64_t width, std::int64_t height, int max_hole_pixels) {
  constexpr const char* kCaller = "fill_small_holes";
  check_size(kCaller, image.size(), width, height);
  if (max_hole_pixels < 0) fail(kCaller, "max_hole_pixels must be >= 0");
  if (max_hole_pixels == 0) return;
  // Background pixels explored: kLarge = in a component too large (or open to the border) to fill, kCurrent = in
  // the component being explored. Filled components turn foreground, so a background pixel met with kLarge
  // means the current component is that large one too.
  constexpr std::uint8_t kLarge = 1;
  constexpr std::uint8_t kCurrent = 2;
  std::vector<std::uint8_t> seen(image.size(), 0);
  std::vector<std::int64_t> visited;
  std::vector<std::int64_t> stack;
  auto foreground = [&](std::int64_t x, std::int64_t y) {
    return x >= 0 && y >= 0 && x < width && y < height && image[static_cast<std::size_t>(y * width + x)] != 0;
  };
  for (std::int64_t y = 0; y < height; ++y) {
    for (std::int64_t x = 0; x < width; ++x) {
      const std::int64_t start = y * width + x;
      if (image[static_cast<std::size_t>(start)] != 0 || seen[static_cast<std::size_t>(start)] != 0) continue;
      // Every small component has a pixel with at least 2 foreground 4-neighbours (one at the end of a branch,
      // or any pixel of a 2×2 block), so only those seed a search; open free space is walked only near walls.
      const int around = (foreground(x - 1, y) ? 1 : 0) + (foreground(x + 1, y) ? 1 : 0) +
                         (foreground(x, y - 1) ? 1 : 0) + (foreground(x, y + 1) ? 1 : 0);
      if (around < 2) continue;
      visited.assign(1, start);
      stack.assign(1, start);
      seen[static_cast<std::size_t>(start)] = kCurrent;
      bool open = false;
      while (!stack.empty() && !open) {
        const std::int64_t i = stack.back();
        stack.pop_back();
        const std::int64_t cx = i % width, cy = i / width;
        if (cx == 0 || cy == 0 || cx == width - 1 || cy == height - 1) {
          open = true;
          break;
        }
        for (const std::int64_t n : {i - 1, i + 1, i - width, i + width}) {
          if (image[static_cast<std::size_t>(n)] != 0) continue;
          const std::uint8_t mark = seen[static_cast<std::size_t>(n)];
          if (mark == kCurrent) continue;
          if (mark == kLarge || static_cast<int>(visited.size()) >= max_hole_pixels) {
            open = true;
            break;
          }
          seen[static_cast<std::size_t>(n)] = kCurrent;
          visited.push_back(n);
          stack.push_back(n);
        }
      }
      for (const std::int64_t i : visited) {
        if (open) {
          seen[static_cast<std::size_t>(i)] = kLarge;
        } else {
          image[static_cast<std::size_t>(i)] = 1;
        }
      }
    }
  }
}

std::vector<std::uint8_t> threshold(const ProbabilityRaster& raster, float p_occupied) {
  if (!(p_occupied > 0.0f && p_occupied <= 1.0f)) {
    fail("threshold", "p_occupied must be in (0, 1], got " + std::to_string(p_occupied));
  }
  validate(raster);
  std::vector<std::uint8_t> out(raster.p.size());
  // NaN compares false, so unknown cells come out 0.
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = raster.p[i] >= p_occupied ? 1 : 0;
  return out;
}

std::vector<std::uint8_t> zhang_suen_thinning(std::span<const std::uint8_t> image, std::int64_t width,
                                              std::int64_t height) {
  check_size("zhang_suen_thinning", image.size(), width, height);
  PaddedImage img(image, width, height);

  // Candidates: foreground pixels that may be deleted. Both tables require a background 4-neighbour, so only
  // border pixels qualify; a pixel becomes border only when a neighbour is deleted.
  std::vector<std::int32_t> candidates;
  std::vector<std::uint8_t> listed(static_cast<std::size_t>((width + 2) * (height + 2)), 0);
  for (std::int64_t y = 0; y < height; ++y) {
    for (std::int64_t x = 0; x < width; ++x) {
      const std::int32_t i = img.index(x, y);
      if (!img.at(i)) continue;
      if (!img.at(img.neighbour(i, 0)) || !img.at(img.neighbour(i, 2)) || !img.at(img.neighbour(i, 4)) ||
          !img.at(img.neighbour(i, 6))) {
        candidates.push_back(i);
        listed[static_cast<std::size_t>(i)] = 1;
      }
    }
  }

  std::vector<std::int32_t> marked;
  std::vector<std::int32_t> deleted;
  for (bool changed = true; changed;) {
    changed = false;
    for (int sub = 0; sub < 2; ++sub) {
      const auto& table = kZhangSuen[static_cast<std::size_t>(sub)];
      marked.clear();
      for (const std::int32_t i : candidates) {
        if (table[img.code(i)]) marked.push_back(i);
      }
      deleted.clear();
      for (const std::int32_t i : marked) {
        // The topology guard: re-check against the image as it is now, after this sub-iteration's deletions.
        const unsigned code = img.code(i);
        if (std::popcount(code) >= 2 && kSimple[code]) {
          img.clear(i);
          deleted.push_back(i);
        }
      }
      if (deleted.empty()) continue;
      changed = true;
      for (const std::int32_t i : deleted) {
        for (int k = 0; k < 8; ++k) {
          const std::int32_t n = img.neighbour(i, k);
          if (img.at(n) && listed[static_cast<std::size_t>(n)] == 0) {
            listed[static_cast<std::size_t>(n)] = 1;
            candidates.push_back(n);
          }
        }
      }
      std::erase_if(candidates, [&](std::int32_t i) { return !img.at(i); });
    }
  }
  return img.unpadded();
}

}  // namespace wm::fusion
