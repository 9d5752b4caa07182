#include "apriori/export/dxf_writer.h"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <stdexcept>

namespace wm::apriori {
namespace {

constexpr std::size_t kMaxR12NameLength = 31;

class Out {
 public:
  void group(int code, std::string_view value) {
    char buffer[8];
    std::snprintf(buffer, sizeof buffer, "%3d", code);
    text_ += buffer;
    text_ += '\n';
    text_ += value;
    text_ += '\n';
  }
  void group(int code, int value) { group(code, std::to_string(value)); }
  /// The shortest fixed-point text that reads back as the same double (exact round trip, no exponent: every DXF
  /// reader takes it).
  void number(int code, double value) {
    if (value == 0.0) value = 0.0;  // no "-0"
    char buffer[400];
    auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, value, std::chars_format::fixed);
    std::string s(buffer, ec == std::errc() ? end : buffer);
    if (s.find('.') == std::string::npos) s += ".0";
    group(code, s);
  }
  void point(int code, const Eigen::Vector2d& p) {
    number(code, p.x());
    number(code + 10, p.y());
    number(code + 20, 0.0);
  }
  std::string take() { return std::move(text_); }

 private:
  std::string text_;
};

void validate(const std::vector<LayerLines>& layers, const char* function) {
  for (const auto& layer : layers) {
    if (layer.layer.empty()) throw std::invalid_argument(std::string(function) + ": empty layer name");
    if (!layer.ids.empty() && layer.ids.size() != layer.polylines.size())
      throw std::invalid_argument(std::string(function) + ": layer '" + layer.layer +
                                  "' has ids that are not one per polyline");
    for (std::size_t i = 0; i < layer.polylines.size(); ++i) {
      const auto& line = layer.polylines[i];
      if (line.size() < 2)
        throw std::invalid_argument(std::string(function) + ": polyline " + std::to_string(i) + " of layer '" +
                                    layer.layer + "' has fewer than 2 points");
      for (const auto& p : line)
        if (!p.allFinite())
          throw std::invalid_argument(std::string(function) + ": polyline " + std::to_string(i) + " of layer '" +
                                      layer.layer + "' has a non-finite coordinate");
    }
  }
}

}  // namespace

std::string dxf_layer_name(const std::string& layer) {
  std::string name;
  for (char c : layer.substr(0, kMaxR12NameLength)) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '$';
    name += ok ? c : '_';
  }
  return name;
}

std::string write_dxf(const std::vector<LayerLines>& layers) {
  validate(layers, "write_dxf");
  for (const auto& layer : layers)
    if (layer.color < 1 || layer.color > 255)
      throw std::invalid_argument("write_dxf: colour of layer '" + layer.layer + "' is not in 1..255");

  Eigen::Vector2d min = Eigen::Vector2d::Zero(), max = Eigen::Vector2d::Zero();
  bool any = false;
  for (const auto& layer : layers)
    for (const auto& line : layer.polylines)
      for (const auto& p : line) {
        min = any ? min.cwiseMin(p) : p;
        max = any ? max.cwiseMax(p) : p;
        any = true;
      }

  Out out;
  out.group(0, "SECTION");
  out.group(2, "HEADER");
  out.group(9, "$ACADVER");
  out.group(1, "AC1009");
  out.group(9, "$INSUNITS");
  out.group(70, 6);  // metres
  out.group(9, "$MEASUREMENT");
  out.group(70, 1);  // metric
  out.group(9, "$EXTMIN");
  out.point(10, min);
  out.group(9, "$EXTMAX");
  out.point(10, max);
  out.group(0, "ENDSEC");

  std::vector<std::pair<std::string, int>> table{{"0", 7}};
  std::set<std::string> seen{"0"};
  for (const auto& layer : layers) {
    auto name = dxf_layer_name(layer.layer);
    if (seen.insert(name).second) table.emplace_back(std::move(name), layer.color);
  }
  out.group(0, "SECTION");
  out.group(2, "TABLES");
  out.group(0, "TABLE");
  out.group(2, "LTYPE");
  out.group(70, 1);
  out.group(0, "LTYPE");
  out.group(2, "CONTINUOUS");
  out.group(70, 0);
  out.group(3, "Solid line");
  out.group(72, 65);
  out.group(73, 0);
  out.number(40, 0.0);
  out.group(0, "ENDTAB");
  out.group(0, "TABLE");
  out.group(2, "LAYER");
  out.group(70, static_cast<int>(table.size()));
  for (const auto& [name, color] : table) {
    out.group(0, "LAYER");
    out.group(2, name);
    out.group(70, 0);
    out.group(62, color);
    out.group(6, "CONTINUOUS");
  }
  out.group(0, "ENDTAB");
  out.group(0, "ENDSEC");
  out.group(0, "SECTION");
  out.group(2, "BLOCKS");
  out.group(0, "ENDSEC");

  out.group(0, "SECTION");
  out.group(2, "ENTITIES");
  for (const auto& layer : layers) {
    const auto name = dxf_layer_name(layer.layer);
    for (const auto& line : layer.polylines) {
      const bool closed = line.size() > 3 && line.front() == line.back();
      const std::size_t count = closed ? line.size() - 1 : line.size();
      if (count == 2) {
        out.group(0, "LINE");
        out.group(8, name);
        out.point(10, line[0]);
        out.point(11, line[1]);
        continue;
      }
      out.group(0, "POLYLINE");
      out.group(8, name);
      out.group(66, 1);
      out.point(10, Eigen::Vector2d::Zero());
      out.group(70, closed ? 1 : 0);
      for (std::size_t i = 0; i < count; ++i) {
        out.group(0, "VERTEX");
        out.group(8, name);
        out.point(10, line[i]);
      }
      out.group(0, "SEQEND");
      out.group(8, name);
    }
  }
  out.group(0, "ENDSEC");
  out.group(0, "EOF");
  return out.take();
}

}  // namespace wm::apriori
