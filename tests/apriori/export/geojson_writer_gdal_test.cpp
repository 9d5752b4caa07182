#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "apriori/export/geojson_writer.h"
#include "tests/support/temp_dir.h"

// The GeoJSON export read back by GDAL (Debian gdal-bin, run as a tool, never linked): GDAL's own geodesic
// lengths, distances and azimuths (SpatiaLite functions of `ogrinfo -dialect SQLite`) check the georeferenced
// coordinates in metres, and its CRS report checks that a local export is not taken for WGS 84 degrees.
// Without ogrinfo these tests fail; they are never skipped.

namespace wm::apriori {
namespace {

/// gtest assertion that `text` contains `part` (the tests do not link gmock's matchers).
::testing::AssertionResult contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << part << "' not found in:\n" << text;
}

struct CommandResult {
  int status = -1;
  std::string output;  // stdout and stderr
};

CommandResult run(const std::string& command) {
  CommandResult r;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (!pipe) throw std::runtime_error("popen failed: " + command);
  char buffer[4096];
  while (const std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) r.output.append(buffer, n);
  const int status = ::pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// Runs `ogrinfo ARGS`; throws (so the test fails) when ogrinfo is missing or fails.
std::string ogrinfo(const std::string& args) {
  if (run("command -v ogrinfo").status != 0)
    throw std::runtime_error("ogrinfo not found: run scripts/setup.sh (it installs Debian's gdal-bin)");
  const auto r = run("ogrinfo " + args);
  if (r.status != 0) throw std::runtime_error("ogrinfo " + args + " failed:\n" + r.output);
  return r.output;
}

/// The rows of `sql` (SQLite dialect, so with SpatiaLite's functions) on the GeoJSON file at `path`, each as
/// field name → value text, parsed from ogrinfo's "  name (Type) = value" lines.
std::vector<std::map<std::string, std::string>> sql_rows(const std::filesystem::path& path, const std::string& sql) {
  const std::string output = ogrinfo("-q -dialect SQLite -sql \"" + sql + "\" " + path.string());
  std::vector<std::map<std::string, std::string>> rows;
  std::size_t start = 0;
  while (start < output.size()) {
    std::size_t end = output.find('\n', start);
    if (end == std::string::npos) end = output.size();
    const std::string line = output.substr(start, end - start);
    start = end + 1;
    if (line.starts_with("OGRFeature(")) {
      rows.emplace_back();
      continue;
    }
    const auto open = line.find(" (");
    const auto equals = line.find(") = ");
    if (rows.empty() || !line.starts_with("  ") || open == std::string::npos || equals == std::string::npos) continue;
    rows.back()[line.substr(2, open - 2)] = line.substr(equals + 4);
  }
  return rows;
}

std::filesystem::path write_file(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

constexpr double kDeg = std::numbers::pi / 180.0;

// A 90 m wall starting 14.45 m from the origin, 25° counter-clockwise of world +x, and a 30 m + 40 m corner.
std::vector<LayerLines> walls() {
  const Eigen::Vector2d start(12.5, -7.25);
  LayerLines layer{"confirmed",
                   {{start, start + 90.0 * Eigen::Vector2d(std::cos(25.0 * kDeg), std::sin(25.0 * kDeg))},
                    {{0.0, 0.0}, {30.0, 0.0}, {30.0, 40.0}}}};
  layer.ids = {"wall-90", "corner-70"};
  return {layer};
}

double number(const std::map<std::string, std::string>& row, const std::string& field) {
  const auto it = row.find(field);
  if (it == row.end()) throw std::runtime_error("ogrinfo printed no field " + field);
  return std::stod(it->second);  // "(null)" throws, failing the test
}

TEST(GeoJsonWriterGdalTest, GdalMeasuresTheGeoreferencedWallInMetres) {
  const testing::TempDir dir;
  const Georeference georeference{52.52, 13.405, 37.5};
  const auto path = write_file(dir.path() / "walls.geojson", write_geojson(walls(), georeference));

  // ogrinfo reads it as WGS 84 (RFC 7946's default), with no warning about the foreign members.
  const std::string summary = ogrinfo("-so -al " + path.string());
  EXPECT_TRUE(contains(summary, "GEOGCRS[\"WGS 84\""));
  EXPECT_TRUE(contains(summary, "ID[\"EPSG\",4326]"));
  EXPECT_FALSE(contains(summary, "Warning"));

  // Lengths and distances on the WGS 84 ellipsoid (use_ellipsoid = 1), azimuths from north. A spherical Earth
  // or a wrong ellipsoid would be off by decimetres; a wrong heading or axis order by metres and degrees.
  const auto rows =
      sql_rows(path,
               "SELECT id, ST_Length(geometry, 1) AS length_m, "
               "ST_Distance(ST_StartPoint(geometry), MakePoint(13.405, 52.52, 4326), 1) AS start_m, "
               "Degrees(ST_Azimuth(ST_StartPoint(geometry), ST_PointN(geometry, 2))) AS bearing_deg FROM walls");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].at("id"), "wall-90");
  EXPECT_NEAR(number(rows[0], "length_m"), 90.0, 1e-3);  // the ground is 2 nm shorter than the tangent plane
  EXPECT_NEAR(number(rows[0], "start_m"), std::hypot(12.5, -7.25), 1e-3);
  // Heading 37.5° minus the wall's 25° counter-clockwise turn; 1e-3° for the meridian convergence at the wall's
  // start (about 2e-4°), 1.6 mm across the wall.
  EXPECT_NEAR(number(rows[0], "bearing_deg"), 12.5, 1e-3);
  EXPECT_EQ(rows[1].at("id"), "corner-70");
  EXPECT_NEAR(number(rows[1], "length_m"), 70.0, 1e-3);
  EXPECT_NEAR(number(rows[1], "start_m"), 0.0, 1e-3);
  EXPECT_NEAR(number(rows[1], "bearing_deg"), 37.5, 1e-3);  // the first leg runs along world +x
}

TEST(GeoJsonWriterGdalTest, GdalDoesNotReadALocalExportAsWgs84Degrees) {
  const testing::TempDir dir;
  const auto path = write_file(dir.path() / "walls.geojson", write_geojson(walls()));

  // Without the "crs" member GDAL 3.6 reports GEOGCRS["WGS 84", ... ID["EPSG",4326]] and a 90 m wall spans 90°.
  // With it, the layer is the engineering CRS, in metres, and GDAL refuses to reproject it to WGS 84.
  const std::string summary = ogrinfo("-so -al " + path.string());
  EXPECT_TRUE(contains(summary, "ENGCRS[\"worldmodel world frame\""));
  EXPECT_TRUE(contains(summary, "LENGTHUNIT[\"metre\",1]"));
  EXPECT_FALSE(contains(summary, "WGS 84"));
  EXPECT_FALSE(contains(summary, "GEOGCRS"));
  // The EPSG code as GDAL prints it: "4326" alone can come up in the temporary directory's random name.
  EXPECT_FALSE(contains(summary, "\"EPSG\",4326"));
  EXPECT_FALSE(contains(summary, "EPSG:4326"));

  // Plane lengths are metres; an ellipsoidal length does not exist for it (SpatiaLite answers NULL).
  const auto rows = sql_rows(path,
                             "SELECT ST_Length(geometry) AS length_m, ST_Length(geometry, 1) AS geodesic_m "
                             "FROM walls");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_NEAR(number(rows[0], "length_m"), 90.0, 1e-9);
  EXPECT_EQ(rows[0].at("geodesic_m"), "(null)");
}

}  // namespace
}  // namespace wm::apriori
