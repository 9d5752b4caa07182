#include "apriori/import/amrl_import.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "apriori/import/json_limits.h"
#include "apriori/internal/plan_builder.h"

namespace wm::apriori {
namespace {

using internal::WorldShape;
using nlohmann::json;

double number(const json& value, const std::string& path) {
  if (!value.is_number()) throw FloorPlanError(path, "expected a number");
  const double v = value.get<double>();
  if (!std::isfinite(v)) throw FloorPlanError(path, "not a finite number");
  return v;
}

Eigen::Vector2d point(const json& segment, const char* key, const std::string& path) {
  const auto ppath = path + "." + key;
  const auto it = segment.find(key);
  if (it == segment.end() || !it->is_object()) throw FloorPlanError(ppath, "expected {\"x\": .., \"y\": ..}");
  const auto x = it->find("x");
  const auto y = it->find("y");
  if (x == it->end()) throw FloorPlanError(ppath + ".x", "missing field");
  if (y == it->end()) throw FloorPlanError(ppath + ".y", "missing field");
  return {number(*x, ppath + ".x"), number(*y, ppath + ".y")};
}

struct Segment {
  Eigen::Vector2d p0, p1;
  std::string path;
};

std::vector<Segment> parse_json(std::string_view text) {
  if (auto error = json_nesting_error(text)) throw FloorPlanError("", *error);
  json doc;
  try {
    doc = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {
    throw FloorPlanError("", std::string("malformed JSON: ") + e.what());
  }
  if (!doc.is_array()) throw FloorPlanError("", "a vector map is a JSON array of {\"p0\", \"p1\"} segments");
  std::vector<Segment> segments;
  for (std::size_t i = 0; i < doc.size(); ++i) {
    const auto path = "[" + std::to_string(i) + "]";
    if (!doc[i].is_object()) throw FloorPlanError(path, "expected {\"p0\": .., \"p1\": ..}");
    segments.push_back({point(doc[i], "p0", path), point(doc[i], "p1", path), path});
  }
  return segments;
}

std::vector<Segment> parse_text(std::string_view text) {
  std::vector<Segment> segments;
  std::size_t line = 0;
  while (!text.empty()) {
    const auto end = text.find('\n');
    std::string_view l = text.substr(0, end);
    text = end == std::string_view::npos ? std::string_view() : text.substr(end + 1);
    ++line;
    if (const auto hash = l.find('#'); hash != std::string_view::npos) l = l.substr(0, hash);
    double v[4];
    std::size_t count = 0;
    std::size_t pos = 0;
    const auto path = "line " + std::to_string(line);
    while (true) {
      while (pos < l.size() && (l[pos] == ' ' || l[pos] == '\t' || l[pos] == ',' || l[pos] == '\r')) ++pos;
      if (pos >= l.size()) break;
      if (count == 4) throw FloorPlanError(path, "expected 4 numbers x0, y0, x1, y1");
      auto [ptr, ec] = std::from_chars(l.data() + pos, l.data() + l.size(), v[count]);
      if (ec != std::errc() || !std::isfinite(v[count]))
        throw FloorPlanError(path, "expected a finite number at column " + std::to_string(pos + 1));
      pos = static_cast<std::size_t>(ptr - l.data());
      ++count;
    }
    if (count == 0) continue;
    if (count != 4) throw FloorPlanError(path, "expected 4 numbers x0, y0, x1, y1");
    segments.push_back({{v[0], v[1]}, {v[2], v[3]}, path});
  }
  return segments;
}

}  // namespace

ImportResult import_amrl_vectormap(std::string_view text, const AmrlImportOptions& options) {
  if (!(std::isfinite(options.min_length_m) && options.min_length_m >= 0.0))
    throw std::invalid_argument("import_amrl_vectormap: min_length_m must be finite and >= 0");
  std::size_t first = 0;
  while (first < text.size() && std::isspace(static_cast<unsigned char>(text[first]))) ++first;
  const bool is_json = first < text.size() && text[first] == '[';
  const auto segments = is_json ? parse_json(text) : parse_text(text);

  ImportResult result;
  auto& report = result.report;
  report.format = "amrl-vectormap";
  report.units_source = "metres (format)";
  report.entity_counts["segments"] = segments.size();
  auto& layer = report.layers["segments"];
  layer.entities = segments.size();
  layer.status = "mapped";
  internal::PlanBuilder builder(options.name, options.limits);
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const auto& s = segments[i];
    internal::check_world_point(s.p0, options.limits.max_abs_coordinate_m, s.path + ".p0");
    internal::check_world_point(s.p1, options.limits.max_abs_coordinate_m, s.path + ".p1");
    if ((s.p1 - s.p0).norm() < std::max(options.min_length_m, 1e-6)) {
      ++report.skipped["shorter than min_length_m"];
      continue;
    }
    if (builder.add("wall-" + std::to_string(i), options.kind, options.attributes, {WorldShape{{s.p0, s.p1}, false}},
                    std::nullopt, s.path))
      ++layer.objects;
  }
  report.objects = builder.size();
  report.extent = builder.extent();
  result.plan = std::move(builder).finish();
  return result;
}

}  // namespace wm::apriori
