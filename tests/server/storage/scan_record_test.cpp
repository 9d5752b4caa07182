// The scan journal's binary form: scans come back bit for bit (so a replay puts into the grid what the first run
// did), and a damaged record, in every way it can be cut or changed, is a StorageError naming the scan, never a
// crash or another exception; a damaged row stops start-up's replay with that error and costs a robot only its pose.
#include "server/storage/scan_record.h"

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstring>
#include <limits>

#include "server/storage/database.h"
#include "server/storage/store.h"
#include "support/temp_dir.h"

namespace wm::storage {
namespace {

world::ScanObservation laser() {
  fusion::LaserScan scan;
  scan.sensor_pose = {12.5, -3.0, 2.9};
  scan.angle_min_rad = -2.35;
  scan.angle_increment_rad = 0.0043633;
  scan.range_min_m = 0.02;
  scan.range_max_m = 25;
  scan.sigma_range_m = 0.015;
  scan.sigma_range_per_m = 0.001;
  scan.usable_range_m = 20;
  scan.ranges_m = {0.1 + 0.2, std::numeric_limits<double>::quiet_NaN(),  std::numeric_limits<double>::infinity(),
                   -1.0,      std::numeric_limits<double>::denorm_min(), 1.0 / 3.0};
  world::ScanObservation observation;
  observation.observer = "robot-7";
  observation.stamp_s = 1700000000.125;
  observation.scan = scan;
  observation.pose_cov << 1e-4, 1e-6, 0, 1e-6, 2e-4, 0, 0, 0, 3e-5;
  return observation;
}

world::ScanObservation sonar() {
  fusion::SonarScan scan;
  scan.sensor_pose = {1, 2, -0.5};
  scan.angles_rad = {0, 0.5, 1.0};
  scan.ranges_m = {1.25, 3.0, 5.0};
  scan.beam_width_rad = 0.4;
  scan.range_max_m = 6;
  world::ScanObservation observation;
  observation.scan = scan;
  return observation;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

TEST(ScanRecordTest, ALaserScanComesBackBitForBit) {
  const auto scan = laser();
  const auto back = decode_scan(encode_scan(scan), "robot-7", scan.stamp_s);
  const auto& a = std::get<fusion::LaserScan>(scan.scan);
  const auto& b = std::get<fusion::LaserScan>(back.scan);
  EXPECT_TRUE(same_bits(a.ranges_m, b.ranges_m));
  EXPECT_EQ(b.sensor_pose.x_m, a.sensor_pose.x_m);
  EXPECT_EQ(b.sensor_pose.theta_rad, a.sensor_pose.theta_rad);
  EXPECT_EQ(b.angle_min_rad, a.angle_min_rad);
  EXPECT_EQ(b.angle_increment_rad, a.angle_increment_rad);
  EXPECT_EQ(b.range_min_m, a.range_min_m);
  EXPECT_EQ(b.range_max_m, a.range_max_m);
  EXPECT_EQ(b.sigma_range_m, a.sigma_range_m);
  EXPECT_EQ(b.sigma_range_per_m, a.sigma_range_per_m);
  EXPECT_EQ(b.usable_range_m, a.usable_range_m);
  EXPECT_EQ(back.pose_cov, scan.pose_cov);
  EXPECT_EQ(back.observer, "robot-7");
  EXPECT_EQ(back.stamp_s, scan.stamp_s);
  EXPECT_STREQ(back.sensor(), "laser");
}

TEST(ScanRecordTest, ASonarScanComesBackBitForBit) {
  const auto scan = sonar();
  const auto back = decode_scan(encode_scan(scan), "s", 0);
  const auto& a = std::get<fusion::SonarScan>(scan.scan);
  const auto& b = std::get<fusion::SonarScan>(back.scan);
  EXPECT_TRUE(same_bits(a.angles_rad, b.angles_rad));
  EXPECT_TRUE(same_bits(a.ranges_m, b.ranges_m));
  EXPECT_EQ(b.beam_width_rad, a.beam_width_rad);
  EXPECT_EQ(b.range_max_m, a.range_max_m);
  EXPECT_EQ(b.sigma_range_m, a.sigma_range_m);
  EXPECT_STREQ(back.sensor(), "sonar");
}

// No readings at all (a sensor that saw nothing): nothing is copied from or to an empty vector's null data().
TEST(ScanRecordTest, AScanWithoutReadingsComesBackEmpty) {
  auto empty_laser = laser();
  std::get<fusion::LaserScan>(empty_laser.scan).ranges_m.clear();
  auto empty_sonar = sonar();
  std::get<fusion::SonarScan>(empty_sonar.scan).ranges_m.clear();
  std::get<fusion::SonarScan>(empty_sonar.scan).angles_rad.clear();
  EXPECT_TRUE(std::get<fusion::LaserScan>(decode_scan(encode_scan(empty_laser), "r", 0).scan).ranges_m.empty());
  EXPECT_TRUE(std::get<fusion::SonarScan>(decode_scan(encode_scan(empty_sonar), "r", 0).scan).angles_rad.empty());
}

// Every cut, every single byte changed to each of a few values, and bytes added: a value or a StorageError.
TEST(ScanRecordTest, EveryTruncationOrChangedByteIsAStorageErrorOrAValidScan) {
  for (const auto& scan : {laser(), sonar()}) {
    const auto good = encode_scan(scan);
    for (std::size_t n = 0; n < good.size(); ++n)
      EXPECT_THROW(decode_scan(std::string_view(good).substr(0, n), "r", 0), StorageError) << "cut at " << n;
    EXPECT_THROW(decode_scan(good + '\0', "r", 0), StorageError);
    std::size_t refused = 0;
    for (std::size_t i = 0; i < good.size(); ++i) {
      for (const unsigned char value : {0x00, 0x7f, 0xff}) {
        auto bad = good;
        bad[i] = static_cast<char>(value);
        try {
          const auto back = decode_scan(bad, "r", 0);
          EXPECT_EQ(encode_scan(back), bad) << "byte " << i;  // what it accepts, it keeps as it was
        } catch (const StorageError&) {
          ++refused;
        }
      }
    }
    EXPECT_GT(refused, 0u);
  }
}

// The StorageError's message for `blob` ("" when it decodes).
std::string error_of(const std::string& blob) {
  try {
    decode_scan(blob, "r", 0);
  } catch (const StorageError& e) {
    return e.what();
  }
  return "";
}

TEST(ScanRecordTest, WhatIsWrongIsNamed) {
  auto magic = encode_scan(laser());
  magic[0] = 'X';
  EXPECT_NE(error_of(magic).find("not a scan record"), std::string::npos);
  auto kind = encode_scan(laser());
  kind[4] = 9;
  EXPECT_NE(error_of(kind).find("unknown kind 9"), std::string::npos);
  // A count far over the limit is refused before anything is allocated for it.
  auto many = encode_scan(laser());
  const std::size_t count_at = 4 + 1 + 12 * 8 + 7 * 8;
  const std::uint32_t huge = 0xffffffffu;
  std::memcpy(many.data() + count_at, &huge, sizeof huge);
  EXPECT_NE(error_of(many).find("more than"), std::string::npos);
  EXPECT_NE(error_of(encode_scan(laser()).substr(0, 30)).find("truncated"), std::string::npos);
  // A pose that is not finite (fusion::validate) is a StorageError too.
  auto nan_pose = laser();
  std::get<fusion::LaserScan>(nan_pose.scan).sensor_pose.x_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(error_of(encode_scan(nan_pose)), "");
}

TEST(ScanRecordTest, ADamagedJournalRowStopsTheReplayWithItsNumberAndCostsItsRobotOnlyItsPose) {
  testing::TempDir dir;
  const auto path = (dir.path() / "a.db").string();
  {
    Store store({path, true});
    const auto a = laser(), b = laser();
    store.commit_scan({1, &a}, std::nullopt);
    store.commit_scan({2, &b}, std::nullopt);
    ASSERT_EQ(store.scans_after(0).size(), 2u);
  }
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(db, "UPDATE scans SET scan = substr(scan, 1, 40) WHERE seq = 2", nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(db);
  Store store({path, true});
  EXPECT_EQ(store.scans_after(2).size(), 0u);
  try {
    store.scans_after(0);
    FAIL() << "a damaged row must not be replayed";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("scan 2 of the journal is damaged"), std::string::npos) << e.what();
  }
  const auto robots = store.robot_journal(10);
  ASSERT_EQ(robots.size(), 1u);
  EXPECT_EQ(robots[0].robot, "robot-7");
  EXPECT_EQ(robots[0].scans.at("laser"), 2);
  EXPECT_FALSE(robots[0].last_scan);
}

}  // namespace
}  // namespace wm::storage
