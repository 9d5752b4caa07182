// The copy-on-write table and the spatial hash that make the world model's per-request copy and its matching cost
// what the neighbourhood holds: sharing between copies, and queries checked against a brute-force scan.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>
#include <string>

#include "server/world/cow_map.h"
#include "server/world/spatial_hash.h"
#include "server/world/world_state.h"

namespace wm::world {
namespace {

fusion::LineSegment segment(double x0, double y0, double x1, double y1) {
  return fusion::LineSegment::from_points({x0, y0}, {x1, y1}, Eigen::Matrix2d::Identity() * 1e-4);
}

TEST(CowMapTest, ACopyKeepsWhatItHadWhileTheOriginalChanges) {
  CowMap<std::string> map;
  for (int k = 0; k < 10000; k += 3) map.put(k, "v" + std::to_string(k));
  const CowMap<std::string> copy = map;
  map.put(3, "changed");
  map.erase(6);
  map.put(20000, "far");
  EXPECT_EQ(copy.at(3), "v3");
  EXPECT_EQ(copy.at(6), "v6");
  EXPECT_FALSE(copy.contains(20000));
  EXPECT_EQ(map.at(3), "changed");
  EXPECT_FALSE(map.contains(6));
  EXPECT_EQ(map.at(20000), "far");
  EXPECT_EQ(copy.size(), 3334u);
  EXPECT_EQ(map.size(), 3334u);
  // Unchanged values are shared, not copied.
  EXPECT_EQ(&copy.at(9999), &map.at(9999));
  EXPECT_THROW(map.at(7), std::out_of_range);
  EXPECT_THROW(map.put(-1, "x"), std::out_of_range);
  EXPECT_EQ(map.find(-5), nullptr);
}

TEST(CowMapTest, IteratesPresentKeysInOrder) {
  CowMap<int> map;
  const std::set<std::int64_t> keys{0, 1, 63, 64, 4095, 4096, 70000};
  for (auto k : keys) map.put(k, static_cast<int>(k) * 2);
  map.put(500, 1);
  map.erase(500);
  std::vector<std::int64_t> seen;
  for (const auto& [k, v] : map) {
    seen.push_back(k);
    EXPECT_EQ(v, k * 2);
  }
  EXPECT_EQ(seen, std::vector<std::int64_t>(keys.begin(), keys.end()));
  map.clear();
  EXPECT_TRUE(map.empty());
  EXPECT_EQ(map.begin(), map.end());
}

TEST(SpatialHashTest, QueriesFindEveryOverlappingBoxAsABruteForceScanDoes) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> position(-500.0, 500.0), length(0.0, 30.0), angle(0.0, 6.3);
  SpatialHash hash;
  std::map<std::int64_t, Box> boxes;
  for (std::int64_t key = 1; key <= 3000; ++key) {
    const double x = position(rng), y = position(rng), l = length(rng), a = angle(rng);
    boxes[key] = Box::of(segment(x, y, x + l * std::cos(a), y + l * std::sin(a)));
    hash.insert(key, boxes[key]);
  }
  // Moves and removals keep the index in step.
  for (std::int64_t key = 1; key <= 3000; key += 7) {
    const Box moved{boxes[key].x0 + 9.0, boxes[key].y0 - 3.0, boxes[key].x1 + 9.0, boxes[key].y1 - 3.0};
    hash.move(key, boxes[key], moved);
    boxes[key] = moved;
  }
  for (std::int64_t key = 2; key <= 3000; key += 11) {
    hash.erase(key, boxes[key]);
    boxes.erase(key);
  }
  // Sizes from a scan line to more than the cell limit (a whole-map excerpt).
  for (const double size : {0.5, 3.0, 40.0, 400.0, 2000.0}) {
    for (int q = 0; q < 40; ++q) {
      const double x = position(rng), y = position(rng);
      const Box query{x, y, x + size, y + size};
      const auto found = hash.query(query);
      EXPECT_TRUE(std::is_sorted(found.begin(), found.end()));
      std::set<std::int64_t> found_set(found.begin(), found.end());
      EXPECT_EQ(found_set.size(), found.size()) << "no repeats";
      for (const auto& [key, box] : boxes) {
        if (box.overlaps(query)) {
          EXPECT_TRUE(found_set.count(key)) << "key " << key << ", query size " << size;
        }
      }
      for (const auto key : found) EXPECT_TRUE(boxes.count(key)) << "removed key " << key << " still found";
    }
  }
}

double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-18), 0.0, 1.0);
  return (p - (a + t * ab)).norm();
}

double segment_distance(const fusion::LineSegment& s, const fusion::LineSegment& t) {
  const Eigen::Vector2d a = s.p0(), b = s.p1(), c = t.p0(), d = t.p1();
  const auto cross = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); };
  const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a), d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
  if (((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0))) return 0.0;
  return std::min({point_segment_distance(a, c, d), point_segment_distance(b, c, d), point_segment_distance(c, a, b),
                   point_segment_distance(d, a, b)});
}

// Segments are kept in the cells they pass, long diagonal walls among them: a query by box finds every segment with
// a point in the box, a query by segment every segment within the margin, as brute force says; after bulk insertion,
// single insertions, moves and removals.
TEST(SpatialHashTest, SegmentsAreFoundFromEveryBoxTheyCrossAndNearEverySegmentTheyPass) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> position(-300.0, 300.0), length(0.0, 20.0), angle(0.0, 6.3);
  std::map<std::int64_t, fusion::LineSegment> segments;
  const auto random_segment = [&](std::int64_t key) {
    const double x = position(rng), y = position(rng), a = angle(rng);
    const double l = key % 10 == 0 ? 150.0 + 3.0 * length(rng) * 10.0 : length(rng);  // a tenth 150-750 m long
    return segment(x, y, x + l * std::cos(a), y + l * std::sin(a));
  };
  std::vector<std::pair<std::int64_t, fusion::LineSegment>> bulk;
  for (std::int64_t key = 1; key <= 1500; ++key) bulk.emplace_back(key, random_segment(key));
  for (const auto& [key, s] : bulk) segments.emplace(key, s);
  SpatialHash hash;
  hash.insert_all(bulk);
  for (std::int64_t key = 1501; key <= 2000; ++key) {
    segments.emplace(key, random_segment(key));
    hash.insert(key, segments.at(key));
  }
  for (std::int64_t key = 1; key <= 2000; key += 7) {
    const auto moved = random_segment(key);
    hash.move(key, segments.at(key), moved);
    segments.insert_or_assign(key, moved);
  }
  for (std::int64_t key = 2; key <= 2000; key += 11) {
    hash.erase(key, segments.at(key));
    segments.erase(key);
  }
  for (int q = 0; q < 60; ++q) {
    const double x = position(rng), y = position(rng), size = q % 2 ? 1.0 : 30.0;
    const Box box{x, y, x + size, y + size};
    const auto by_box = hash.query(box);
    const std::set<std::int64_t> found_by_box(by_box.begin(), by_box.end());
    const auto probe = random_segment(q);
    const double margin = q % 3 == 0 ? 0.0 : 2.5;
    const auto by_segment = hash.query(probe, margin);
    EXPECT_TRUE(std::is_sorted(by_segment.begin(), by_segment.end()));
    const std::set<std::int64_t> found_by_segment(by_segment.begin(), by_segment.end());
    EXPECT_EQ(found_by_segment.size(), by_segment.size()) << "no repeats";
    for (const auto& [key, s] : segments) {
      if (box.crossed_by(s)) {
        EXPECT_TRUE(found_by_box.count(key)) << "key " << key << " crosses box " << q;
      }
      const double distance = segment_distance(s, probe);
      if (distance < margin - 1e-9 || (margin == 0.0 && distance == 0.0)) {
        EXPECT_TRUE(found_by_segment.count(key)) << "key " << key << " near probe " << q;
      }
    }
    for (const auto key : by_box) EXPECT_TRUE(segments.count(key)) << "removed key " << key << " still found";
    for (const auto key : by_segment) EXPECT_TRUE(segments.count(key)) << "removed key " << key << " still found";
  }
}

TEST(SpatialHashTest, AHugeBoxAndFarCoordinatesStayFindable) {
  SpatialHash hash;
  const Box huge{-5000, -5000, 5000, 5000}, far{1e15, 1e15, 1e15 + 1, 1e15 + 1};
  hash.insert(1, huge);
  hash.insert(2, far);
  EXPECT_EQ(hash.query({0, 0, 1, 1}), std::vector<std::int64_t>{1});
  EXPECT_EQ(hash.query({1e15, 1e15, 1e15 + 2, 1e15 + 2}), (std::vector<std::int64_t>{1, 2}));
  hash.move(1, huge, {0, 0, 1, 1});
  EXPECT_EQ(hash.query({3000, 3000, 3001, 3001}), std::vector<std::int64_t>{});
  hash.erase(2, far);
  EXPECT_EQ(hash.query({1e15, 1e15, 1e15 + 2, 1e15 + 2}), std::vector<std::int64_t>{});
}

TEST(ElementTableTest, NearFollowsPutsAndErasesAndCopiesStayApart) {
  ElementTable table;
  Element e;
  e.number = 1;
  e.segment = segment(0, 0, 3, 0);
  table.put(e);
  e.number = 2;
  e.segment = segment(100, 100, 101, 100);
  table.put(e);
  const ElementTable before = table;
  e.number = 1;
  e.segment = segment(50, 50, 52, 50);  // element 1 moves (a join may do that)
  table.put(e);
  table.erase(2);
  EXPECT_EQ(table.near({-1, -1, 4, 1}), std::vector<std::int64_t>{});
  EXPECT_EQ(table.near({49, 49, 53, 51}), std::vector<std::int64_t>{1});
  EXPECT_EQ(table.near({99, 99, 102, 101}), std::vector<std::int64_t>{});
  EXPECT_EQ(before.near({-1, -1, 4, 1}), std::vector<std::int64_t>{1});
  EXPECT_EQ(before.near({99, 99, 102, 101}), std::vector<std::int64_t>{2});
  EXPECT_NEAR(before.at(1).segment.p1().x(), 3.0, 1e-9);
  EXPECT_THROW(table.put(Element{}), std::out_of_range) << "numbers start at 1";
}

}  // namespace
}  // namespace wm::world
