// POST /api/v1/scans bodies: CBOR decodes to the document JSON gives and is refused for the same reasons with the same
// field paths; float32 typed arrays (RFC 8746 tag 85); batches validated whole before anything is applied.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "server/json/codec.h"
#include "server/json/codec_error.h"

namespace wm::json_codec {
namespace {

using nlohmann::json;

const char* const kLaser =
    R"({"sensor": "laser", "observer": "r1", "stamp": 12.5, "pose": {"x": 1, "y": 2, "theta": 0.5},
  "angle_min": -0.1, "angle_increment": 0.1, "ranges": [2, null, 2.5], "range_min": 0.1, "range_max": 8,
  "sigma_range": 0.02, "pose_cov": [[1e-4, 0, 0], [0, 1e-4, 0], [0, 0, 1e-5]]})";
const char* const kSonar = R"({"sensor": "sonar", "pose": {"x": 0, "y": 0, "theta": 0}, "angles": [0, 0.5],
  "ranges": [1.5, 2], "range_max": 5, "beam_width": 0.4})";

std::string cbor_of(const json& doc) {
  const auto bytes = json::to_cbor(doc);
  return std::string(bytes.begin(), bytes.end());
}

// A CBOR byte string of little-endian float32s under tag 85 (0xd8 0x55), as a robot would write it.
json::binary_t float32_array(const std::vector<float>& values) {
  std::vector<std::uint8_t> bytes;
  for (const float v : values) {
    const auto bits = std::bit_cast<std::uint32_t>(v);
    for (int k = 0; k < 4; ++k) bytes.push_back(static_cast<std::uint8_t>(bits >> (8 * k)));
  }
  return json::binary_t(bytes, kCborFloat32LeTag);
}

std::string refusal(std::string_view body, BodyFormat format, const ScanLimits& limits = {}) {
  try {
    parse_scan_body(body, format, limits);
  } catch (const CodecError& e) {
    EXPECT_EQ(e.kind(), CodecError::Kind::bad_request);
    return e.what();
  }
  return "<accepted>";
}

void expect_same_scan(const world::ScanObservation& a, const world::ScanObservation& b) {
  EXPECT_EQ(a.observer, b.observer);
  EXPECT_EQ(a.stamp_s, b.stamp_s);
  EXPECT_EQ(a.pose_cov, b.pose_cov);
  ASSERT_EQ(a.scan.index(), b.scan.index());
  if (const auto* laser = std::get_if<fusion::LaserScan>(&a.scan)) {
    const auto& other = std::get<fusion::LaserScan>(b.scan);
    EXPECT_EQ(laser->sensor_pose.x_m, other.sensor_pose.x_m);
    EXPECT_EQ(laser->sensor_pose.theta_rad, other.sensor_pose.theta_rad);
    EXPECT_EQ(laser->angle_min_rad, other.angle_min_rad);
    EXPECT_EQ(laser->angle_increment_rad, other.angle_increment_rad);
    EXPECT_EQ(laser->range_min_m, other.range_min_m);
    EXPECT_EQ(laser->range_max_m, other.range_max_m);
    EXPECT_EQ(laser->sigma_range_m, other.sigma_range_m);
    ASSERT_EQ(laser->ranges_m.size(), other.ranges_m.size());
    for (std::size_t i = 0; i < laser->ranges_m.size(); ++i) {
      if (std::isnan(laser->ranges_m[i])) {
        EXPECT_TRUE(std::isnan(other.ranges_m[i])) << i;
      } else {
        EXPECT_EQ(laser->ranges_m[i], other.ranges_m[i]) << i;
      }
    }
  } else {
    const auto& sonar = std::get<fusion::SonarScan>(a.scan);
    const auto& other = std::get<fusion::SonarScan>(b.scan);
    EXPECT_EQ(sonar.angles_rad, other.angles_rad);
    EXPECT_EQ(sonar.ranges_m, other.ranges_m);
    EXPECT_EQ(sonar.beam_width_rad, other.beam_width_rad);
  }
}

TEST(ScanBodyTest, ACborScanIsTheScanOfTheSameJson) {
  for (const char* text : {kLaser, kSonar}) {
    const auto from_json = parse_scan_body(text, BodyFormat::json, {});
    const auto from_cbor = parse_scan_body(cbor_of(json::parse(text)), BodyFormat::cbor, {});
    EXPECT_FALSE(from_json.batch);
    EXPECT_FALSE(from_cbor.batch);
    ASSERT_EQ(from_cbor.scans.size(), 1u);
    expect_same_scan(from_json.scans[0], from_cbor.scans[0]);
  }
  // A null range is no reading in both.
  const auto scan = parse_scan_body(cbor_of(json::parse(kLaser)), BodyFormat::cbor, {}).scans[0];
  EXPECT_TRUE(std::isnan(std::get<fusion::LaserScan>(scan.scan).ranges_m[1]));
}

TEST(ScanBodyTest, RangesMayBeAFloat32TypedArray) {
  auto doc = json::parse(kLaser);
  doc["ranges"] = float32_array({2.0f, 0.3f, 7.75f});
  const auto cbor = cbor_of(doc);
  // tag 85 (0xd8 0x55) over a 12-byte byte string (0x4c): the wire form the README documents.
  EXPECT_NE(cbor.find("\xd8\x55\x4c"), std::string::npos);
  const auto scan = parse_scan_body(cbor, BodyFormat::cbor, {}).scans[0];
  const auto& ranges = std::get<fusion::LaserScan>(scan.scan).ranges_m;
  ASSERT_EQ(ranges.size(), 3u);
  EXPECT_EQ(ranges[0], 2.0);
  EXPECT_EQ(ranges[1], static_cast<double>(0.3f));
  EXPECT_EQ(ranges[2], 7.75);

  auto sonar = json::parse(kSonar);
  sonar["angles"] = float32_array({0.0f, 0.5f});
  sonar["ranges"] = float32_array({1.5f, 2.0f});
  const auto sonar_scan =
      std::get<fusion::SonarScan>(parse_scan_body(cbor_of(sonar), BodyFormat::cbor, {}).scans[0].scan);
  EXPECT_EQ(sonar_scan.angles_rad, (std::vector<double>{0.0, 0.5}));
  EXPECT_EQ(sonar_scan.ranges_m, (std::vector<double>{1.5, 2.0}));
}

TEST(ScanBodyTest, AFloat32ArrayFollowsTheRulesOfJsonNumbers) {
  const auto with_ranges = [](const json::binary_t& ranges) {
    auto doc = json::parse(kLaser);
    doc["ranges"] = ranges;
    return refusal(cbor_of(doc), BodyFormat::cbor);
  };
  // JSON has no NaN or Inf: a number must be finite (null is the "no reading" a typed array cannot hold).
  EXPECT_EQ(with_ranges(float32_array({2.0f, std::numeric_limits<float>::quiet_NaN()})),
            "ranges[1]: not a finite number");
  EXPECT_EQ(with_ranges(float32_array({std::numeric_limits<float>::infinity()})), "ranges[0]: not a finite number");
  EXPECT_EQ(with_ranges(float32_array({-std::numeric_limits<float>::infinity()})), "ranges[0]: not a finite number");
  EXPECT_EQ(with_ranges(float32_array({2.0f, 2e9f})), "ranges[1]: absurd value");
  EXPECT_EQ(with_ranges(float32_array({})), "ranges: must not be empty");
  EXPECT_EQ(with_ranges(json::binary_t({0, 0, 0, 64, 0}, kCborFloat32LeTag)),
            "ranges: a float32 array needs 4 bytes per value");
  EXPECT_EQ(with_ranges(json::binary_t({0, 0, 0, 64})).substr(0, 30), "ranges: expected an array of n");
  EXPECT_EQ(with_ranges(json::binary_t({0, 0, 0, 64}, 86)).substr(0, 30), "ranges: expected an array of n");
  ScanLimits two_beams;
  two_beams.max_beams = 2;
  auto doc = json::parse(kLaser);
  doc["ranges"] = float32_array({1.0f, 1.0f, 1.0f});
  EXPECT_EQ(refusal(cbor_of(doc), BodyFormat::cbor, two_beams), "ranges: more than 2 values");
  // The same in a plain CBOR array: a float that is NaN or infinite (CBOR can write them; JSON cannot).
  doc["ranges"] = json::array({2.0, std::numeric_limits<double>::quiet_NaN()});
  EXPECT_EQ(refusal(cbor_of(doc), BodyFormat::cbor), "ranges[1]: not a finite number");
}

// Every refusal of a JSON scan body, posted as the CBOR of the same document: the same answer, word for word.
TEST(ScanBodyTest, EveryJsonRefusalIsTheSameForCbor) {
  const std::string pose = R"("pose": {"x": 0, "y": 0, "theta": 0})";
  const std::string laser = R"("sensor": "laser", )" + pose + R"(, "angle_min": 0, "angle_increment": 0.1)";
  const std::vector<std::string> bad = {
      R"([1, 2])",
      R"("laser")",
      R"({})",
      R"({"sensor": "radar"})",
      R"({"sensor": 7})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "colour": "red"})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "observer": ""})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "observer": "a\u0001"})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "observer": "a", "source": "b"})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "stamp": "now"})",
      R"({"sensor": "laser", "angle_min": 0, "angle_increment": 0.1, "ranges": [1], "range_max": 8})",
      R"({"sensor": "laser", "pose": [0, 0, 0], "angle_min": 0, "angle_increment": 0.1, "ranges": [1], "range_max": 8})",
      R"({"sensor": "laser", "pose": {"x": 0, "y": 0}, "angle_min": 0, "angle_increment": 0.1, "ranges": [1], "range_max": 8})",
      R"({"sensor": "laser", "pose": {"x": 0, "y": 0, "theta": 0, "z": 1}, "angle_min": 0, "angle_increment": 0.1, "ranges": [1], "range_max": 8})",
      R"({"sensor": "laser", "pose": {"x": 1e6, "y": 0, "theta": 0}, "angle_min": 0, "angle_increment": 0.1, "ranges": [1], "range_max": 8})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "pose_cov": [[1, 0], [0, 1]]})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "pose_cov": [[1, 0, 0], [0, 1, 0], [0, 0, "x"]]})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "pose_cov": [[1, 2, 0], [2, 1, 0], [0, 0, 1]]})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "pose_cov": [[1, 0, 0], [0.5, 1, 0], [0, 0, 1]]})",
      "{" + laser + R"(, "ranges": [1]})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "range_min": -1})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "range_min": 9})",
      "{" + laser + R"(, "ranges": [1], "range_max": 5000})",
      "{" + laser + R"(, "range_max": 8})",
      "{" + laser + R"(, "ranges": 1, "range_max": 8})",
      "{" + laser + R"(, "ranges": [], "range_max": 8})",
      "{" + laser + R"(, "ranges": [1, "x"], "range_max": 8})",
      "{" + laser + R"(, "ranges": [1, true], "range_max": 8})",
      "{" + laser + R"(, "ranges": [1, 1e10], "range_max": 8})",
      "{" + laser + R"(, "ranges": [1, [2]], "range_max": 8})",
      R"({"sensor": "laser", )" + pose + R"(, "angle_increment": 0.1, "ranges": [1], "range_max": 8})",
      R"({"sensor": "laser", )" + pose + R"(, "angle_min": 0, "angle_increment": 0, "ranges": [1], "range_max": 8})",
      R"({"sensor": "laser", )" + pose + R"(, "angle_min": 0, "angle_increment": 2, "ranges": [1], "range_max": 8})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "sigma_range": 0})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "sigma_range": 11})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "sigma_range_per_m": -1})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "usable_range": 0})",
      "{" + laser + R"(, "ranges": [1], "range_max": 8, "beam_width": 0.3})",
      R"({"sensor": "sonar", )" + pose + R"(, "ranges": [1], "range_max": 8})",
      R"({"sensor": "sonar", )" + pose + R"(, "angles": [0, 1], "ranges": [1], "range_max": 8})",
      R"({"sensor": "sonar", )" + pose + R"(, "angles": [11], "ranges": [1], "range_max": 8})",
      R"({"sensor": "sonar", )" + pose + R"(, "angles": [null], "ranges": [1], "range_max": 8})",
      R"({"sensor": "sonar", )" + pose + R"(, "angles": [0], "ranges": [1], "range_max": 8, "beam_width": 4})",
      R"({"sensor": "sonar", )" + pose + R"(, "angles": [0], "ranges": [1], "range_max": 8, "angle_min": 0})",
      R"({"scans": []})",
      R"({"scans": {}})",
      R"({"scans": [{}], "observer": "r"})",
      R"({"scans": [7]})",
  };
  for (const auto& text : bad) {
    const auto from_json = refusal(text, BodyFormat::json);
    EXPECT_NE(from_json, "<accepted>") << text;
    EXPECT_EQ(refusal(cbor_of(json::parse(text)), BodyFormat::cbor), from_json) << text;
  }
}

TEST(ScanBodyTest, MalformedOrHostileCborIsRefusedWithA400) {
  const auto cbor = [](std::initializer_list<int> bytes) {
    std::string s;
    for (const int b : bytes) s.push_back(static_cast<char>(b));
    return s;
  };
  EXPECT_EQ(refusal("", BodyFormat::cbor).substr(0, 15), "malformed CBOR:");
  EXPECT_EQ(refusal(cbor({0xa1, 0x61}), BodyFormat::cbor).substr(0, 15), "malformed CBOR:");        // cut short
  EXPECT_EQ(refusal(cbor({0xa0, 0x00}), BodyFormat::cbor).substr(0, 15), "malformed CBOR:");        // trailing byte
  EXPECT_EQ(refusal(cbor({0xa1, 0x01, 0x02}), BodyFormat::cbor).substr(0, 15), "malformed CBOR:");  // integer key
  EXPECT_EQ(refusal(cbor({0xf7}), BodyFormat::cbor).substr(0, 15), "malformed CBOR:");              // undefined
  EXPECT_EQ(refusal(cbor({0xc1, 0x00}), BodyFormat::cbor).substr(0, 15), "malformed CBOR:");        // tag 1 (a time)
  // An array that says it holds 2^64 − 1 items: refused, nothing reserved for them.
  EXPECT_EQ(refusal(cbor({0x9b, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xfe}), BodyFormat::cbor).substr(0, 15),
            "malformed CBOR:");
  // Nesting as deep as a body allows bytes (each 0x81 opens an array).
  const std::string deep(100000, '\x81');
  EXPECT_NE(refusal(deep + '\x00', BodyFormat::cbor).find("nested deeper than"), std::string::npos);
  // A million one-byte values would be a 16 MB document.
  ScanLimits small;
  small.max_beams = 10;
  small.max_batch_scans = 1;
  std::string many = cbor({0x9a, 0x00, 0x0f, 0x42, 0x40});  // array of 1 000 000
  many.append(1000000, '\xf6');
  EXPECT_NE(refusal(many, BodyFormat::cbor, small).find("values in one body"), std::string::npos);
  // Text that is not UTF-8, as a value or as a key (a JSON body with it is refused by the JSON parser).
  EXPECT_NE(refusal(cbor({0xa1, 0x68, 's', 'e', 'n', 's', 'o', 'r', 0x61, 0xff}), BodyFormat::cbor).find("not UTF-8"),
            std::string::npos);
  EXPECT_NE(refusal(cbor({0xa1, 0x61, 0xc0, 0x00}), BodyFormat::cbor).find("not UTF-8"), std::string::npos);
}

TEST(ScanBodyTest, ABatchIsValidatedWholeAndNamesItsBadScan) {
  const auto laser = json::parse(kLaser);
  const auto sonar = json::parse(kSonar);
  const json batch = {{"scans", {laser, sonar, laser}}};
  for (const auto format : {BodyFormat::json, BodyFormat::cbor}) {
    const auto body = format == BodyFormat::json ? batch.dump() : cbor_of(batch);
    const auto parsed = parse_scan_body(body, format, {});
    EXPECT_TRUE(parsed.batch);
    ASSERT_EQ(parsed.scans.size(), 3u);
    EXPECT_TRUE(std::holds_alternative<fusion::LaserScan>(parsed.scans[0].scan));
    EXPECT_TRUE(std::holds_alternative<fusion::SonarScan>(parsed.scans[1].scan));
    expect_same_scan(parsed.scans[2], parse_scan(kLaser, {}));

    auto bad = batch;
    bad["scans"][1]["ranges"][1] = "far";
    const auto bad_body = format == BodyFormat::json ? bad.dump() : cbor_of(bad);
    EXPECT_EQ(refusal(bad_body, format), "scans[1].ranges[1]: expected a number");
    bad = batch;
    bad["scans"][2].erase("pose");
    EXPECT_EQ(refusal(format == BodyFormat::json ? bad.dump() : cbor_of(bad), format),
              "scans[2].pose: missing field (the sensor pose in the world)");
    bad = batch;
    bad["scans"][1]["beam_width"] = 3.0;  // wider than the grid's sonar model takes: the scan as a whole is refused
    const auto whole = refusal(format == BodyFormat::json ? bad.dump() : cbor_of(bad), format);
    EXPECT_EQ(whole.substr(0, 23), "scans[1]: invalid scan:") << whole;
  }
  ScanLimits two;
  two.max_batch_scans = 2;
  EXPECT_EQ(refusal(batch.dump(), BodyFormat::json, two), "scans: more than 2 scans in one batch");
  EXPECT_EQ(parse_scan_body(json({{"scans", {laser}}}).dump(), BodyFormat::json, two).scans.size(), 1u);
}

}  // namespace
}  // namespace wm::json_codec
