#include "logs/carmen_log_reader.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "fusion/grid/occupancy_grid.h"
#include "support/temp_dir.h"
#include "support/test_data.h"

namespace wm::logs {
namespace {

const std::filesystem::path kTestData = WM_TEST_DATA_DIR;
constexpr double kPi = std::numbers::pi;

std::vector<LogScan> read_all(const std::filesystem::path& path, const CarmenReaderOptions& options = {}) {
  CarmenLogReader reader(path, options);
  std::vector<LogScan> out;
  while (auto s = reader.next()) out.push_back(std::move(*s));
  return out;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

void write_gzip(const std::filesystem::path& path, const std::string& text) {
  gzFile f = gzopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  ASSERT_EQ(gzwrite(f, text.data(), static_cast<unsigned>(text.size())), static_cast<int>(text.size()));
  gzclose(f);
}

std::string read_text(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// An independent reading of a plain FLASER log: istringstream tokens, no shared code with the reader.
struct ReferenceScan {
  std::size_t line;
  std::vector<double> ranges;
  double x, y, theta, stamp;
};
std::vector<ReferenceScan> reference_flaser(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::vector<ReferenceScan> out;
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    std::istringstream tokens(line);
    std::string type;
    tokens >> type;
    if (type != "FLASER") continue;
    ReferenceScan s{number, {}, 0, 0, 0, 0};
    std::size_t n = 0;
    tokens >> n;
    s.ranges.resize(n);
    for (double& r : s.ranges) tokens >> r;
    double odom = 0;
    tokens >> s.x >> s.y >> s.theta >> odom >> odom >> odom >> s.stamp;
    out.push_back(s);
  }
  return out;
}

TEST(CarmenLogReaderTest, ReadsPlainFreiburgExcerptWithLaserOffsetAndHalfDegreeBeams) {
  const auto path = kTestData / "carmen" / "freiburg-079-corrected-excerpt.log";
  const auto reference = reference_flaser(path);
  ASSERT_EQ(reference.size(), 12u);
  const auto scans = read_all(path);
  ASSERT_EQ(scans.size(), reference.size());
  for (std::size_t i = 0; i < scans.size(); ++i) {
    const LogScan& s = scans[i];
    const ReferenceScan& r = reference[i];
    EXPECT_EQ(s.line_number, r.line);
    EXPECT_EQ(s.scan.ranges_m, r.ranges);
    EXPECT_DOUBLE_EQ(s.timestamp_s, r.stamp);
    // PARAM robot_frontlaser_offset -0.04: the laser sits 4 cm behind the robot's centre, along its heading.
    EXPECT_NEAR(s.scan.sensor_pose.x_m, r.x - 0.04 * std::cos(r.theta), 1e-12);
    EXPECT_NEAR(s.scan.sensor_pose.y_m, r.y - 0.04 * std::sin(r.theta), 1e-12);
    EXPECT_DOUBLE_EQ(s.scan.sensor_pose.theta_rad, r.theta);
    ASSERT_EQ(s.scan.ranges_m.size(), 360u);
    EXPECT_DOUBLE_EQ(s.scan.angle_min_rad, -kPi / 2);
    EXPECT_DOUBLE_EQ(s.scan.angle_increment_rad, kPi / 360);  // 0.5°, last beam at +89.5°
    EXPECT_DOUBLE_EQ(s.scan.range_max_m, 50.0);
    EXPECT_NO_THROW(fusion::validate(s.scan));
  }
  EXPECT_EQ(scans.front().line_number, 192u);
}

TEST(CarmenLogReaderTest, ReadsGzippedIntelExcerptInLineOrder) {
  const auto path = kTestData / "carmen" / "intel-corrected-excerpt.log.gz";
  CarmenLogReader reader(path);
  std::vector<LogScan> scans;
  double last_progress = 0.0;
  while (auto s = reader.next()) {
    EXPECT_GE(reader.progress(), last_progress);
    last_progress = reader.progress();
    scans.push_back(std::move(*s));
  }
  EXPECT_DOUBLE_EQ(reader.progress(), 1.0);
  ASSERT_EQ(scans.size(), 35u);
  EXPECT_EQ(reader.lines_read(), 822u);
  EXPECT_EQ(reader.skipped_lines(), 822u - 35u);
  // Facts of the log text (zcat | awk): first scan on line 175, 180 beams, pose (0.600266, −0.0320327, −0.354665).
  const LogScan& first = scans.front();
  EXPECT_EQ(first.line_number, 175u);
  ASSERT_EQ(first.scan.ranges_m.size(), 180u);
  EXPECT_DOUBLE_EQ(first.scan.ranges_m[0], 1.09);
  EXPECT_DOUBLE_EQ(first.scan.ranges_m[1], 1.08);
  EXPECT_DOUBLE_EQ(first.scan.sensor_pose.x_m, 0.600266);  // offset 0.0 in intel
  EXPECT_DOUBLE_EQ(first.scan.sensor_pose.y_m, -0.0320327);
  EXPECT_DOUBLE_EQ(first.scan.sensor_pose.theta_rad, -0.354665);
  EXPECT_DOUBLE_EQ(first.timestamp_s, 32.9068);
  EXPECT_DOUBLE_EQ(first.scan.angle_increment_rad, kPi / 180);  // 1°, −90° … +89°
  // The log's own time goes backwards at line 769; the reader keeps line order.
  EXPECT_EQ(scans[33].line_number, 760u);
  EXPECT_EQ(scans[34].line_number, 769u);
  EXPECT_LT(scans[34].timestamp_s, scans[33].timestamp_s);
}

TEST(CarmenLogReaderTest, PlainAndGzippedFilesGiveTheSameScans) {
  const wm::testing::TempDir dir;
  const auto plain = kTestData / "carmen" / "freiburg-079-corrected-excerpt.log";
  write_gzip(dir.path() / "f.log.gz", read_text(plain));
  const auto a = read_all(plain);
  const auto b = read_all(dir.path() / "f.log.gz");
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].line_number, b[i].line_number);
    EXPECT_EQ(a[i].scan.ranges_m, b[i].scan.ranges_m);
    EXPECT_EQ(a[i].scan.sensor_pose.x_m, b[i].scan.sensor_pose.x_m);
  }
}

TEST(CarmenLogReaderTest, ParsesHandWrittenLinesAndSkipsUnknownOnes) {
  const wm::testing::TempDir dir;
  std::ostringstream flaser;
  flaser << "FLASER 181";
  for (int i = 0; i < 181; ++i) flaser << ' ' << 1 + i % 7;
  flaser << " 1.5 -2.0 0.5 1.5 -2.0 0.5 1234.5 host 0.25";
  const std::string flaser181 = flaser.str();
  const std::string robotlaser =
      "ROBOTLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 5 1.0 2.0 8.5 nan 3.0 2 10 20 "
      "4.0 5.0 0.25 3.9 5.1 0.2 0 0 0 0 0 99.75 b21 0.5";
  std::ostringstream text;
  text << "# a comment\r\n"
       << "PARAM robot_frontlaser_offset 0.5 nohost 0\n"
       << "ODOM 0 0 0 0 0 0 0.1 host 0.1\n"
       << "\n"
       << "FOO bar baz\n"
       << flaser181 << "\r\n"  // CRLF tolerated
       << "NEFF 12.5\n"
       << robotlaser;  // no newline at the end
  write_text(dir.path() / "hand.log", text.str());
  CarmenLogReader reader(dir.path() / "hand.log");
  const auto f = reader.next();
  ASSERT_TRUE(f);
  EXPECT_EQ(f->line_number, 6u);
  EXPECT_EQ(reader.skipped_lines(), 5u);
  ASSERT_EQ(f->scan.ranges_m.size(), 181u);
  EXPECT_DOUBLE_EQ(f->scan.ranges_m[180], 1 + 180 % 7);
  EXPECT_DOUBLE_EQ(f->scan.angle_min_rad, -kPi / 2);
  EXPECT_DOUBLE_EQ(f->scan.angle_min_rad + 180 * f->scan.angle_increment_rad, kPi / 2);  // 181 beams: both ends
  EXPECT_NEAR(f->scan.sensor_pose.x_m, 1.5 + 0.5 * std::cos(0.5), 1e-12);
  EXPECT_NEAR(f->scan.sensor_pose.y_m, -2.0 + 0.5 * std::sin(0.5), 1e-12);
  EXPECT_DOUBLE_EQ(f->timestamp_s, 1234.5);

  const auto r = reader.next();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->line_number, 8u);
  EXPECT_DOUBLE_EQ(r->scan.angle_min_rad, -1.0);
  EXPECT_DOUBLE_EQ(r->scan.angle_increment_rad, 0.5);
  EXPECT_DOUBLE_EQ(r->scan.range_max_m, 8.0);
  ASSERT_EQ(r->scan.ranges_m.size(), 5u);
  EXPECT_DOUBLE_EQ(r->scan.ranges_m[2], 8.5);      // >= max range: "no return", kept for the grid to clear
  EXPECT_TRUE(std::isnan(r->scan.ranges_m[3]));    // ignored per beam by the grid
  EXPECT_DOUBLE_EQ(r->scan.sensor_pose.x_m, 4.0);  // the laser pose, not the robot pose
  EXPECT_DOUBLE_EQ(r->scan.sensor_pose.theta_rad, 0.25);
  EXPECT_DOUBLE_EQ(r->timestamp_s, 99.75);

  EXPECT_FALSE(reader.next());
  EXPECT_FALSE(reader.next());
  EXPECT_EQ(reader.lines_read(), 8u);
  EXPECT_EQ(reader.skipped_lines(), 6u);
  EXPECT_DOUBLE_EQ(reader.progress(), 1.0);
}

// The line that must fail, after one good line; the error names the file and line 2.
void expect_error_on_line_2(const std::string& bad_line, const std::string& reason_part) {
  const wm::testing::TempDir dir;
  const auto path = dir.path() / "bad.log";
  std::ostringstream text;
  text << "ODOM 0 0 0 0 0 0 0.1 host 0.1\n" << bad_line << "\n";
  write_text(path, text.str());
  CarmenLogReader reader(path);
  try {
    reader.next();
    ADD_FAILURE() << "no LogError for: " << bad_line;
  } catch (const LogError& e) {
    EXPECT_EQ(e.line(), 2u);
    EXPECT_EQ(e.file(), path);
    const std::string what = e.what();
    EXPECT_NE(what.find(path.string() + ":2:"), std::string::npos) << what;
    EXPECT_NE(what.find(reason_part), std::string::npos) << what;
  }
}

TEST(CarmenLogReaderTest, MalformedKnownLinesThrowWithFileAndLine) {
  expect_error_on_line_2("FLASER 3 1 2 3 0 0 0 0 0 0 5 host", "fields, expected 14");
  expect_error_on_line_2("FLASER 3 1 2 3 0 0 0 0 0 0 5 host 6 7", "fields, expected 14");
  expect_error_on_line_2("FLASER 3 1 x 3 0 0 0 0 0 0 5 host 6", "range is not a number");
  expect_error_on_line_2("FLASER 3 1 2 3 nan 0 0 0 0 0 5 host 6", "pose is not finite");
  expect_error_on_line_2("FLASER -3 1 2 3", "not a count");
  expect_error_on_line_2("FLASER", "without a reading count");
  expect_error_on_line_2("FLASER 1 1 0 0 0 0 0 0 5 host 6", "at least 2 readings");
  expect_error_on_line_2("ROBOTLASER1 0 -1.0 2.0 0.5 8.0 0.01 0 2 1 2 0 0 0 0 0 0 0 0 0 0 0 0 1 h", "fields");
  expect_error_on_line_2("ROBOTLASER1 0 -1.0 2.0 0.5 -8.0 0.01 0 2 1 2 0 0 0 0 0 0 0 0 0 0 0 0 1 h 2", "maximum_range");
  expect_error_on_line_2("ROBOTLASER1 0 -1.0", "too short");
  expect_error_on_line_2("PARAM robot_frontlaser_offset abc nohost 0", "not a number");
}

TEST(CarmenLogReaderTest, MissingFileThrowsLogErrorForLineZero) {
  try {
    CarmenLogReader reader(kTestData / "carmen" / "does-not-exist.log");
    ADD_FAILURE() << "no LogError";
  } catch (const LogError& e) {
    EXPECT_EQ(e.line(), 0u);
  }
}

TEST(CarmenLogReaderTest, TruncatedGzipThrowsAfterTheScansBeforeTheCut) {
  const wm::testing::TempDir dir;
  const std::string whole = read_text(kTestData / "carmen" / "intel-corrected-excerpt.log.gz");
  write_text(dir.path() / "cut.log.gz", whole.substr(0, whole.size() / 2));
  CarmenLogReader reader(dir.path() / "cut.log.gz");
  std::size_t scans = 0;
  EXPECT_THROW(
      {
        while (reader.next()) ++scans;
      },
      LogError);
  EXPECT_GT(scans, 5u);
  EXPECT_LT(scans, 35u);
}

TEST(CarmenLogReaderTest, ReadsTheRealRobotLaser1Log) {
  // No copy in tests/data: the file states no licence (tests/data/carmen/SOURCE.md).
  const auto scans = read_all(testing::real_data("csail-robotlaser1/csail.log"));
  // Counts and first/last values from the file's text (its SOURCE.md gives the same count).
  ASSERT_EQ(scans.size(), 686u);
  for (const LogScan& s : scans) {
    ASSERT_EQ(s.scan.ranges_m.size(), 361u);
    EXPECT_DOUBLE_EQ(s.scan.angle_min_rad, -1.570796);
    EXPECT_DOUBLE_EQ(s.scan.angle_increment_rad, 0.008727);
    EXPECT_DOUBLE_EQ(s.scan.range_max_m, 80.0);
  }
  EXPECT_EQ(scans.front().line_number, 1u);
  EXPECT_EQ(scans.back().line_number, 686u);
  EXPECT_DOUBLE_EQ(scans.front().scan.ranges_m[0], 81.91);
  EXPECT_DOUBLE_EQ(scans.front().timestamp_s, 1134864642.914187);
  EXPECT_DOUBLE_EQ(scans.back().timestamp_s, 1134865040.453204);
  EXPECT_DOUBLE_EQ(scans.back().scan.sensor_pose.x_m, -0.579904);
  EXPECT_DOUBLE_EQ(scans.back().scan.sensor_pose.theta_rad, 0.733895);
}

// The reference the issue compares with: a naive 5 cm Bayes grid — Bresenham from the sensor's cell to the return's
// cell, p_hit 0.7 at the return, p_miss 0.4 before it, clamped to [−2, 3.5], no per-scan rule, no beam width.
class NaiveGrid {
 public:
  void insert(const fusion::LaserScan& s, double usable_range_m) {
    const fusion::GridGeometry g({0, 0}, 0.05, 1, 1);
    const fusion::CellIndex a = g.cell_of({s.sensor_pose.x_m, s.sensor_pose.y_m});
    for (std::size_t i = 0; i < s.ranges_m.size(); ++i) {
      double r = s.ranges_m[i];
      if (!(r >= s.range_min_m)) continue;
      const bool hit = r < s.range_max_m && r <= usable_range_m;
      if (!hit) r = std::min(s.range_max_m, usable_range_m);
      const double t = s.sensor_pose.theta_rad + s.angle_min_rad + static_cast<double>(i) * s.angle_increment_rad;
      const fusion::CellIndex b = g.cell_of({s.sensor_pose.x_m + r * std::cos(t), s.sensor_pose.y_m + r * std::sin(t)});
      const std::int64_t dx = std::abs(b.x - a.x), dy = -std::abs(b.y - a.y);
      const std::int64_t sx = a.x < b.x ? 1 : -1, sy = a.y < b.y ? 1 : -1;
      std::int64_t err = dx + dy, x = a.x, y = a.y;
      while (x != b.x || y != b.y) {
        add(x, y, kMiss);
        const std::int64_t e2 = 2 * err;
        if (e2 >= dy) err += dy, x += sx;
        if (e2 <= dx) err += dx, y += sy;
      }
      add(b.x, b.y, hit ? kHit : kMiss);
    }
  }
  bool occupied(std::int64_t x, std::int64_t y) const {
    const auto it = cells_.find({x, y});
    return it != cells_.end() && it->second > 0.0;
  }

 private:
  static constexpr double kHit = 0.8472978603872037;    // logit(0.7)
  static constexpr double kMiss = -0.4054651081081644;  // logit(0.4)
  void add(std::int64_t x, std::int64_t y, double v) {
    double& l = cells_[{x, y}];
    l = std::clamp(l + v, -2.0, 3.5);
  }
  std::map<std::pair<std::int64_t, std::int64_t>, double> cells_;
};

// The whole Intel log through the reader into a 5 cm grid (default options: 2° laser): the returns, placed by their
// corrected poses, land within one cell of an occupied cell at least as often as in the naive grid — the issue's
// end-to-end criterion, here without the server.
TEST(CarmenLogReaderTest, IntelLogBuildsAGridWhoseWallsHoldTheReturns) {
  const auto scans = read_all(testing::real_data("carmen/intel-corrected.log.gz", "carmen/intel-corrected.log.gz"));
  ASSERT_EQ(scans.size(), 910u);  // SOURCE.md
  const fusion::GridOptions options;
  fusion::OccupancyGrid grid(options);
  NaiveGrid naive;
  for (const LogScan& s : scans) {
    grid.insert(s.scan);
    naive.insert(s.scan, options.sensor.max_usable_range_m);
  }
  const fusion::GridGeometry cells({0, 0}, 0.05, 1, 1);
  std::size_t returns = 0, bayes_hits = 0, ds_hits = 0, naive_hits = 0;
  for (const LogScan& s : scans) {
    for (std::size_t i = 0; i < s.scan.ranges_m.size(); ++i) {
      const double r = s.scan.ranges_m[i];
      if (!(r >= s.scan.range_min_m && r < s.scan.range_max_m && r <= options.sensor.max_usable_range_m)) continue;
      const double a =
          s.scan.sensor_pose.theta_rad + s.scan.angle_min_rad + static_cast<double>(i) * s.scan.angle_increment_rad;
      const fusion::CellIndex c =
          cells.cell_of({s.scan.sensor_pose.x_m + r * std::cos(a), s.scan.sensor_pose.y_m + r * std::sin(a)});
      bool bayes = false, ds = false, reference = false;
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          bayes = bayes || grid.probability({c.x + dx, c.y + dy}) > 0.5;
          const auto m = grid.masses({c.x + dx, c.y + dy});
          ds = ds || m.occupied > m.empty;  // pignistic P(O) > 0.5
          reference = reference || naive.occupied(c.x + dx, c.y + dy);
        }
      }
      ++returns;
      bayes_hits += bayes;
      ds_hits += ds;
      naive_hits += reference;
    }
  }
  const auto fraction = [&](std::size_t n) { return static_cast<double>(n) / static_cast<double>(returns); };
  std::printf("Intel: %zu returns within one cell of an occupied cell: Bayes %.4f, DS %.4f, naive Bayes %.4f\n",
              returns, fraction(bayes_hits), fraction(ds_hits), fraction(naive_hits));
  EXPECT_GE(fraction(bayes_hits), fraction(naive_hits));
  // DS: 0.936 when written (below the naive grid: Dempster's rule turns a grazing ray's miss into conflict where
  // Bayes lets the hit win); a regression guard, not the target.
  EXPECT_GE(fraction(ds_hits), 0.92);
}

}  // namespace
}  // namespace wm::logs
