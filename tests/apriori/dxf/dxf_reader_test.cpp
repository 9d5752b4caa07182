#include "apriori/dxf/dxf_reader.h"

#include <gtest/gtest.h>

#include "apriori/floor_plan.h"
#include "tests/apriori/dxf_text.h"

namespace wm::apriori::dxf {
namespace {

using test::dxf_block;
using test::dxf_file;
using test::dxf_insert;
using test::dxf_line;

std::string error_path(const std::string& text) {
  try {
    read_dxf(text);
  } catch (const FloorPlanError& e) {
    return e.path();
  }
  return "<no error>";
}

std::string error_message(const std::string& text) {
  try {
    read_dxf(text);
  } catch (const FloorPlanError& e) {
    return e.what();
  }
  return "<no error>";
}

std::string crlf(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '\n') out += '\r';
    out += c;
  }
  return out;
}

TEST(DxfReaderTest, ReadsHeaderAndEntitiesWithCrlfLineEndings) {
  const auto doc = read_dxf(crlf(dxf_file(dxf_line("2F", "Walls", 0, 0, 3.5, -1) +
                                          "  0\nARC\n  5\n30\n  8\nDoors\n 10\n1\n 20\n2\n 40\n0.5\n 50\n-90\n 51\n90\n"
                                          "210\n0\n220\n0\n230\n-1\n")));
  EXPECT_EQ(doc.version, "AC1015");
  ASSERT_TRUE(doc.insunits);
  EXPECT_EQ(*doc.insunits, 6);
  ASSERT_EQ(doc.entities.size(), 2u);
  const auto& line = doc.entities[0];
  EXPECT_EQ(line.type, "LINE");
  EXPECT_EQ(line.handle, "2F");
  EXPECT_EQ(line.layer, "Walls");
  EXPECT_EQ(line.line, 25u);
  EXPECT_EQ(std::get<Line>(line.shape).end, Eigen::Vector3d(3.5, -1, 0));
  const auto& arc = std::get<Arc>(doc.entities[1].shape);
  EXPECT_EQ(arc.radius, 0.5);
  EXPECT_EQ(arc.start_angle_deg, -90.0);
  EXPECT_EQ(doc.entities[1].extrusion, Eigen::Vector3d(0, 0, -1));
  EXPECT_EQ(doc.entity_counts.at("LINE"), 1u);
  EXPECT_EQ(doc.entity_counts.at("ARC"), 1u);
}

TEST(DxfReaderTest, ReadsLwpolylineVerticesBulgesAndClosedFlag) {
  const auto doc = read_dxf(dxf_file(
      "  0\nLWPOLYLINE\n  5\nA\n  8\nP\n 90\n3\n 70\n1\n 38\n2.5\n 10\n0\n 20\n0\n 42\n1\n 10\n2\n 20\n0\n 10\n2\n 20\n"
      "1\n 42\n-0.5\n"));
  const auto& p = std::get<Polyline>(doc.entities.at(0).shape);
  ASSERT_EQ(p.vertices.size(), 3u);
  EXPECT_TRUE(p.closed);
  EXPECT_FALSE(p.is_3d);
  EXPECT_EQ(p.elevation, 2.5);
  EXPECT_EQ(p.vertices[0].bulge, 1.0);
  EXPECT_EQ(p.vertices[1].bulge, 0.0);
  EXPECT_EQ(p.vertices[2].point, Eigen::Vector2d(2, 1));
  EXPECT_EQ(p.vertices[2].bulge, -0.5);
}

TEST(DxfReaderTest, ReadsOldStylePolylinesAndSkipsMeshesAndControlPoints) {
  const std::string vertex = "  0\nVERTEX\n  8\nP\n";
  const auto doc =
      read_dxf(dxf_file("  0\nPOLYLINE\n  5\nB\n  8\nP\n 66\n1\n 70\n0\n" + vertex + " 10\n0\n 20\n0\n 42\n0.25\n" +
                        vertex + " 70\n16\n 10\n5\n 20\n5\n" + vertex + " 10\n1\n 20\n0\n  0\nSEQEND\n  8\nP\n" +
                        "  0\nPOLYLINE\n  5\nC\n  8\nP\n 66\n1\n 70\n64\n" + vertex + " 10\n0\n 20\n0\n  0\nSEQEND\n" +
                        dxf_line("D", "P", 0, 0, 1, 1)));
  ASSERT_EQ(doc.entities.size(), 2u);
  const auto& p = std::get<Polyline>(doc.entities[0].shape);
  ASSERT_EQ(p.vertices.size(), 2u);  // the spline frame control point (flag 16) is not on the curve
  EXPECT_EQ(p.vertices[0].bulge, 0.25);
  EXPECT_EQ(doc.entities[1].type, "LINE");  // reading continues after the mesh's SEQEND
  EXPECT_EQ(doc.skipped_entities.at("POLYLINE (mesh)"), 1u);
  EXPECT_EQ(doc.entity_counts.at("POLYLINE"), 2u);
}

TEST(DxfReaderTest, CountsUnsupportedAndPaperSpaceEntitiesWithoutKeepingThem) {
  const auto doc = read_dxf(dxf_file("  0\nTEXT\n  5\n1\n  8\n0\n  1\nhello\n 10\n0\n 20\n0\n 40\n1\n" +
                                     dxf_line("2", "0", 0, 0, 1, 0) +
                                     "  0\nLINE\n  5\n3\n 67\n1\n  8\n0\n 10\n0\n 20\n"
                                     "0\n 11\n1\n 21\n1\n  0\nHATCH\n  5\n4\n  8\n0\n"));
  EXPECT_EQ(doc.entities.size(), 1u);
  EXPECT_EQ(doc.skipped_entities.at("TEXT"), 1u);
  EXPECT_EQ(doc.skipped_entities.at("HATCH"), 1u);
  EXPECT_EQ(doc.paper_space_entities, 1u);
  EXPECT_EQ(doc.entity_counts.at("LINE"), 1u);  // model space only
  EXPECT_EQ(doc.entity_counts.at("TEXT"), 1u);
}

TEST(DxfReaderTest, ReadsBlocksAndSkipsInsertAttributes) {
  const std::string attrib = "  0\nATTRIB\n  8\n0\n  1\nvalue\n  2\nTAG\n 10\n0\n 20\n0\n";
  const auto doc =
      read_dxf(dxf_file(dxf_insert("10", "F", "chair", 5, 6, 2.0, 90.0).substr(0) + " 66\n1\n" + attrib + attrib +
                            "  0\nSEQEND\n  8\nF\n" + dxf_line("11", "W", 0, 0, 1, 0),
                        dxf_block("Chair", dxf_line("20", "0", 0, 0, 1, 1) + "  0\nTEXT\n  8\n0\n", 0.5, 0.25)));
  ASSERT_EQ(doc.entities.size(), 2u);
  const auto& ins = std::get<Insert>(doc.entities[0].shape);
  EXPECT_EQ(ins.block, "chair");
  EXPECT_EQ(ins.scale, Eigen::Vector3d(2, 2, 1));
  EXPECT_EQ(ins.rotation_deg, 90.0);
  EXPECT_EQ(doc.entities[1].handle, "11");
  const Block* block = doc.find_block("CHAIR");  // block names compare case-insensitively
  ASSERT_NE(block, nullptr);
  EXPECT_EQ(block->name, "Chair");
  EXPECT_EQ(block->base_point, Eigen::Vector3d(0.5, 0.25, 0));
  EXPECT_EQ(block->entities.size(), 1u);
  EXPECT_EQ(block->skipped_entities.at("TEXT"), 1u);
  EXPECT_EQ(doc.find_block("table"), nullptr);
}

TEST(DxfReaderTest, SkipsCommentsAndUnknownSections) {
  const auto doc = read_dxf("999\nmade by hand\n  0\nSECTION\n  2\nCLASSES\n  0\nCLASS\n  1\nX\n  0\nENDSEC\n" +
                            dxf_file(dxf_line("1", "0", 0, 0, 1, 0)));
  EXPECT_EQ(doc.entities.size(), 1u);
}

TEST(DxfReaderTest, DecodesNamesToUtf8) {
  const auto doc = read_dxf(dxf_file(dxf_line("1",
                                              "M\xF6"
                                              "bel",
                                              0, 0, 1, 0) +  // Latin-1 (pre-2007 file)
                                     dxf_line("2", "M\\U+00F6bel", 0, 0, 1, 0) +
                                     dxf_line("3", "Möbel", 0, 0, 1, 0)));
  for (const auto& e : doc.entities) EXPECT_EQ(e.layer, "Möbel") << e.handle;
}

TEST(DxfReaderTest, SyntaxErrorsNameTheLine) {
  EXPECT_EQ(error_path("  0\nSECTION\n  2\nENTITIES\nX\nLINE\n"), "line 5");  // not a group code
  EXPECT_EQ(error_path(dxf_file("  0\nLINE\n  8\n0\n 10\n1.5.2\n 20\n0\n 11\n1\n 21\n1\n")), "line 30");
  EXPECT_EQ(error_path(dxf_file("  0\nLINE\n  8\n0\n 10\nnan\n 20\n0\n 11\n1\n 21\n1\n")), "line 30");
  EXPECT_EQ(error_path(dxf_file("  0\nLINE\n  8\n0\n 10\n1e999\n 20\n0\n 11\n1\n 21\n1\n")), "line 30");
  EXPECT_EQ(error_path("  0\nSECTION\n  2\nENTITIES\n  0\nLINE\n  8\n"), "line 7");  // code without value
  EXPECT_NE(error_message("  0\nSECTION\n  2\nENTITIES\n  0\nENDSEC\n").find("EOF marker missing"), std::string::npos);
  EXPECT_NE(error_message("  0\nSECTION\n  2\nENTITIES\n" + dxf_line("1", "0", 0, 0, 1, 1)).find("no ENDSEC"),
            std::string::npos);
  EXPECT_NE(error_message("  0\nSECTION\n  2\nBLOCKS\n  0\nBLOCK\n  2\nA\n  0\nENDSEC\n  0\nEOF\n").find("no ENDBLK"),
            std::string::npos);
  EXPECT_EQ(error_path(std::string("  0\nSECTION\n  2\nENTITIES\n\0\n", 27)), "line 5");
  EXPECT_EQ(error_path("  0\nTABLE\n"), "line 1");  // not a SECTION
}

TEST(DxfReaderTest, RefusesBinaryDxfAndDwg) {
  EXPECT_NE(error_message(std::string("AutoCAD Binary DXF\r\n\x1a\0", 22)).find("binary DXF is not supported"),
            std::string::npos);
  EXPECT_NE(error_message(std::string("AC1027\0\0\0\0", 10)).find("DWG"), std::string::npos);
}

TEST(DxfReaderTest, GeometryErrorsNameTheEntity) {
  EXPECT_EQ(error_path(dxf_file("  0\nCIRCLE\n  5\n2F\n  8\n0\n 10\n0\n 20\n0\n 40\n0\n")), "entity CIRCLE handle 2F");
  EXPECT_EQ(error_path(dxf_file("  0\nLINE\n  5\n30\n  8\n0\n 10\n0\n 20\n0\n")), "entity LINE handle 30");
  EXPECT_EQ(error_path(dxf_file("  0\nLINE\n  8\n0\n 10\n0\n 20\n0\n")), "entity LINE at line 25");
  EXPECT_EQ(error_path(dxf_file(dxf_insert("31", "0", "A", 0, 0, 0.0))), "entity INSERT handle 31");
  EXPECT_EQ(error_path(dxf_file("  0\nARC\n  5\n32\n  8\n0\n 10\n0\n 20\n0\n 40\n1\n 50\n0\n 51\n90\n230\n0\n")),
            "entity ARC handle 32");                                                        // zero extrusion vector
  EXPECT_EQ(error_path(dxf_file("", dxf_block("A", "") + dxf_block("a", ""))), "line 39");  // duplicate block
}

TEST(DxfReaderTest, ConvertsInsunitsToMetres) {
  EXPECT_EQ(*insunits_to_metres(4), 1e-3);
  EXPECT_EQ(*insunits_to_metres(1), 0.0254);
  EXPECT_EQ(*insunits_to_metres(2), 0.3048);
  EXPECT_DOUBLE_EQ(*insunits_to_metres(21), 0.3048006096012192);  // US survey foot
  EXPECT_FALSE(insunits_to_metres(0));
  EXPECT_FALSE(insunits_to_metres(99));
  EXPECT_EQ(insunits_name(4), "millimetres");
  EXPECT_EQ(insunits_name(-1), "unknown");
}

}  // namespace
}  // namespace wm::apriori::dxf
