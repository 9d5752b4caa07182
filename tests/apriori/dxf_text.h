#pragma once

// Hand-written DXF snippets for the reader and importer tests: the smallest files that show one behaviour each.

#include <cstdio>
#include <string>

namespace wm::apriori::test {

/// A whole ASCII DXF file: HEADER (with `header` group codes), BLOCKS (`blocks`), ENTITIES (`entities`), EOF.
inline std::string dxf_file(const std::string& entities, const std::string& blocks = "",
                            const std::string& header = "  9\n$ACADVER\n  1\nAC1015\n  9\n$INSUNITS\n 70\n6\n") {
  return "  0\nSECTION\n  2\nHEADER\n" + header + "  0\nENDSEC\n  0\nSECTION\n  2\nBLOCKS\n" + blocks +
         "  0\nENDSEC\n  0\nSECTION\n  2\nENTITIES\n" + entities + "  0\nENDSEC\n  0\nEOF\n";
}

inline std::string num(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.17g", v);
  return buffer;
}

/// LINE with handle (empty: none) on layer.
inline std::string dxf_line(const std::string& handle, const std::string& layer, double x0, double y0, double x1,
                            double y1) {
  return "  0\nLINE\n" + (handle.empty() ? std::string() : "  5\n" + handle + "\n") + "  8\n" + layer + "\n 10\n" +
         num(x0) + "\n 20\n" + num(y0) + "\n 30\n0.0\n 11\n" + num(x1) + "\n 21\n" + num(y1) + "\n 31\n0.0\n";
}

inline std::string dxf_circle(const std::string& handle, const std::string& layer, double x, double y, double r) {
  return "  0\nCIRCLE\n  5\n" + handle + "\n  8\n" + layer + "\n 10\n" + num(x) + "\n 20\n" + num(y) + "\n 40\n" +
         num(r) + "\n";
}

inline std::string dxf_insert(const std::string& handle, const std::string& layer, const std::string& block, double x,
                              double y, double scale = 1.0, double rotation_deg = 0.0) {
  return "  0\nINSERT\n  5\n" + handle + "\n  8\n" + layer + "\n  2\n" + block + "\n 10\n" + num(x) + "\n 20\n" +
         num(y) + "\n 41\n" + num(scale) + "\n 42\n" + num(scale) + "\n 50\n" + num(rotation_deg) + "\n";
}

inline std::string dxf_block(const std::string& name, const std::string& entities, double base_x = 0.0,
                             double base_y = 0.0) {
  return "  0\nBLOCK\n  8\n0\n  2\n" + name + "\n 70\n0\n 10\n" + num(base_x) + "\n 20\n" + num(base_y) +
         "\n 30\n0.0\n  3\n" + name + "\n" + entities + "  0\nENDBLK\n  8\n0\n";
}

}  // namespace wm::apriori::test
