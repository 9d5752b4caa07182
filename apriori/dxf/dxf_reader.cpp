#include "apriori/dxf/dxf_reader.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <span>

#include "apriori/floor_plan.h"
#include "common/utf8.h"

namespace wm::apriori::dxf {
namespace {

// Larger grids are almost certainly corrupt and would multiply the work of every later step.
constexpr int kMaxMinsertCells = 10000;

struct Token {
  int code;
  std::string_view value;
  std::size_t line;  // 1-based line of the group code
};

std::string line_path(std::size_t line) { return "line " + std::to_string(line); }

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::string shorten(std::string_view s) {
  std::string out(s.substr(0, 40));
  for (auto& c : out)
    if (static_cast<unsigned char>(c) < 0x20) c = '?';
  return s.size() > 40 ? out + "..." : out;
}

bool valid_utf8(std::string_view s) { return !common::invalid_utf8_offset(s); }

void append_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out += static_cast<char>(cp);
  } else if (cp < 0x800) {
    out += static_cast<char>(0xC0 | (cp >> 6));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else if (cp < 0x10000) {
    out += static_cast<char>(0xE0 | (cp >> 12));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  } else {
    out += static_cast<char>(0xF0 | (cp >> 18));
    out += static_cast<char>(0x80 | ((cp >> 12) & 0x3F));
    out += static_cast<char>(0x80 | ((cp >> 6) & 0x3F));
    out += static_cast<char>(0x80 | (cp & 0x3F));
  }
}

// Names (layers, blocks) as UTF-8: pre-2007 files are in a Windows code page, read as Latin-1 (exact for the
// letters of Western European languages); \U+XXXX escapes, used by AutoCAD for characters outside the code page,
// are decoded in every version.
std::string decode_name(std::string_view raw) {
  std::string text;
  if (valid_utf8(raw)) {
    text.assign(raw);
  } else {
    for (unsigned char c : raw) append_utf8(text, c);
  }
  if (text.find("\\U+") == std::string::npos) return text;
  std::string out;
  for (std::size_t i = 0; i < text.size();) {
    if (text.compare(i, 3, "\\U+") == 0 && i + 7 <= text.size()) {
      std::uint32_t cp = 0;
      const auto* first = text.data() + i + 3;
      auto [ptr, ec] = std::from_chars(first, first + 4, cp, 16);
      if (ec == std::errc() && ptr == first + 4 && cp != 0 && !(cp >= 0xD800 && cp <= 0xDFFF)) {
        append_utf8(out, cp);
        i += 7;
        continue;
      }
    }
    out += text[i++];
  }
  return out;
}

std::vector<Token> tokenize(std::string_view text) {
  if (text.starts_with("AutoCAD Binary DXF"))
    throw FloorPlanError("", "binary DXF is not supported: save the drawing as ASCII DXF");
  if (text.starts_with("AC10") && text.substr(0, 256).find('\0') != std::string_view::npos)
    throw FloorPlanError("", "this is a DWG file, not a DXF file: export the drawing as ASCII DXF");
  if (text.starts_with("\xEF\xBB\xBF")) text.remove_prefix(3);  // UTF-8 byte order mark
  if (text.find('\0') != std::string_view::npos) {
    const auto at = text.find('\0');
    const auto line = 1 + static_cast<std::size_t>(std::count(text.begin(), text.begin() + at, '\n'));
    throw FloorPlanError(line_path(line), "NUL byte: this is not a text DXF file");
  }
  std::vector<Token> tokens;
  std::size_t pos = 0;
  std::size_t line = 0;
  auto next_line = [&]() -> std::optional<std::string_view> {
    if (pos >= text.size()) return std::nullopt;
    const auto end = text.find('\n', pos);
    std::string_view l = end == std::string_view::npos ? text.substr(pos) : text.substr(pos, end - pos);
    pos = end == std::string_view::npos ? text.size() : end + 1;
    ++line;
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    return l;
  };
  while (auto code_line = next_line()) {
    const auto code_text = trim(*code_line);
    if (code_text.empty() && pos >= text.size()) break;  // a trailing empty line after EOF
    const std::size_t code_line_number = line;
    int code = 0;
    auto [ptr, ec] = std::from_chars(code_text.data(), code_text.data() + code_text.size(), code);
    if (code_text.empty() || ec != std::errc() || ptr != code_text.data() + code_text.size() || code < 0 || code > 1071)
      throw FloorPlanError(line_path(code_line_number),
                           "expected a group code (an integer 0..1071), got '" + shorten(code_text) + "'");
    auto value = next_line();
    if (!value)
      throw FloorPlanError(line_path(code_line_number),
                           "truncated file: group code " + std::to_string(code) + " has no value");
    tokens.push_back({code, *value, code_line_number});
  }
  return tokens;
}

double parse_double(const Token& t) {
  auto s = trim(t.value);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0.0;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec == std::errc::invalid_argument || ptr != s.data() + s.size())
    throw FloorPlanError(line_path(t.line + 1), "expected a number for group code " + std::to_string(t.code) +
                                                    ", got '" + shorten(t.value) + "'");
  if (ec == std::errc::result_out_of_range || !std::isfinite(v))
    throw FloorPlanError(line_path(t.line + 1), "number out of range (must be finite): '" + shorten(t.value) + "'");
  return v;
}

int parse_int(const Token& t) {
  auto s = trim(t.value);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  long long v = 0;
  auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || ptr != s.data() + s.size() || v < -2147483647LL || v > 2147483647LL)
    throw FloorPlanError(line_path(t.line + 1), "expected an integer for group code " + std::to_string(t.code) +
                                                    ", got '" + shorten(t.value) + "'");
  return static_cast<int>(v);
}

/// The group codes of one entity: from its "0 TYPE" token (excluded) to the next "0" token.
class Record {
 public:
  Record(const Token& head, std::span<const Token> body) : head_(head), body_(body) {}

  std::string_view type() const { return head_.value; }
  std::size_t line() const { return head_.line; }
  std::span<const Token> body() const { return body_; }

  const Token* find(int code) const {
    for (const auto& t : body_)
      if (t.code == code) return &t;
    return nullptr;
  }
  double number(int code, double fallback) const {
    const auto* t = find(code);
    return t ? parse_double(*t) : fallback;
  }
  int integer(int code, int fallback) const {
    const auto* t = find(code);
    return t ? parse_int(*t) : fallback;
  }
  std::optional<std::string> text(int code) const {
    const auto* t = find(code);
    if (!t) return std::nullopt;
    return decode_name(trim(t->value));
  }

 private:
  const Token& head_;
  std::span<const Token> body_;
};

std::string describe(std::string_view type, const std::string& handle, std::size_t line) {
  std::string s = "entity " + std::string(type);
  return handle.empty() ? s + " at line " + std::to_string(line) : s + " handle " + handle;
}

double required(const Record& r, int code, const Entity& e, const char* what) {
  const auto* t = r.find(code);
  if (!t)
    throw FloorPlanError(e.describe(), std::string("missing ") + what + " (group code " + std::to_string(code) + ")");
  return parse_double(*t);
}

Eigen::Vector3d required_point(const Record& r, int code, const Entity& e, const char* what) {
  return {required(r, code, e, what), required(r, code + 10, e, what), r.number(code + 20, 0.0)};
}

Eigen::Vector3d extrusion_of(const Record& r, const Entity& e) {
  Eigen::Vector3d n(r.number(210, 0.0), r.number(220, 0.0), r.number(230, 1.0));
  const double length = n.norm();
  if (!(length > 1e-12)) throw FloorPlanError(e.describe(), "zero extrusion direction (group codes 210/220/230)");
  return n / length;
}

void fill_common(const Record& r, Entity& e) {
  e.type = std::string(r.type());
  e.line = r.line();
  if (auto h = r.text(5)) e.handle = *h;
  if (auto layer = r.text(8); layer && !layer->empty()) e.layer = *layer;
}

Polyline parse_lwpolyline(const Record& r, const Entity& e) {
  Polyline p;
  p.closed = (r.integer(70, 0) & 1) != 0;
  p.elevation = r.number(38, 0.0);
  bool have_y = true;
  for (const auto& t : r.body()) {
    if (t.code == 10) {
      if (!have_y)
        throw FloorPlanError(e.describe(), "vertex without y (group code 20) at line " + std::to_string(t.line));
      p.vertices.push_back({{parse_double(t), 0.0}, 0.0});
      have_y = false;
    } else if (t.code == 20) {
      if (p.vertices.empty() || have_y)
        throw FloorPlanError(e.describe(), "y (group code 20) without x at line " + std::to_string(t.line));
      p.vertices.back().point.y() = parse_double(t);
      have_y = true;
    } else if (t.code == 42) {
      if (p.vertices.empty()) throw FloorPlanError(e.describe(), "bulge before the first vertex");
      p.vertices.back().bulge = parse_double(t);
    }
  }
  if (!have_y) throw FloorPlanError(e.describe(), "last vertex has no y (group code 20)");
  return p;
}

class Parser {
 public:
  explicit Parser(std::vector<Token> tokens) : t_(std::move(tokens)) {}

  Document parse() {
    Document doc;
    while (true) {
      if (at_end()) throw FloorPlanError(line_path(last_line()), "truncated file: EOF marker missing");
      const Token& tok = t_[i_];
      if (tok.code == 999) {  // comment
        ++i_;
        continue;
      }
      if (tok.code != 0)
        throw FloorPlanError(line_path(tok.line),
                             "expected '0' starting SECTION or EOF, got group code " + std::to_string(tok.code));
      const auto what = trim(tok.value);
      if (what == "EOF") break;
      if (what != "SECTION")
        throw FloorPlanError(line_path(tok.line), "expected SECTION or EOF, got '" + shorten(what) + "'");
      ++i_;
      if (at_end() || t_[i_].code != 2)
        throw FloorPlanError(line_path(tok.line), "SECTION without a name (group code 2)");
      const auto name = trim(t_[i_].value);
      const std::size_t section_line = tok.line;
      ++i_;
      if (name == "HEADER") {
        parse_header(doc, section_line);
      } else if (name == "ENTITIES") {
        parse_entities(doc, section_line);
      } else if (name == "BLOCKS") {
        parse_blocks(doc, section_line);
      } else {
        skip_section(name, section_line);
      }
    }
    return doc;
  }

 private:
  bool at_end() const { return i_ >= t_.size(); }
  std::size_t last_line() const { return t_.empty() ? 1 : t_.back().line + 1; }

  [[noreturn]] void truncated(std::string_view section, std::size_t section_line) const {
    throw FloorPlanError(line_path(last_line()), "truncated file: section " + std::string(section) + " (line " +
                                                     std::to_string(section_line) + ") has no ENDSEC");
  }

  bool at_endsec() const { return t_[i_].code == 0 && trim(t_[i_].value) == "ENDSEC"; }

  void skip_section(std::string_view name, std::size_t section_line) {
    while (!at_end() && !at_endsec()) ++i_;
    if (at_end()) truncated(name, section_line);
    ++i_;
  }

  void parse_header(Document& doc, std::size_t section_line) {
    while (!at_end() && !at_endsec()) {
      const Token& var = t_[i_++];
      if (var.code != 9) continue;
      const auto name = trim(var.value);
      if (at_end()) break;
      const Token& value = t_[i_];
      if (name == "$ACADVER" && value.code == 1) doc.version = std::string(trim(value.value));
      if (name == "$INSUNITS" && value.code == 70) doc.insunits = parse_int(value);
    }
    if (at_end()) truncated("HEADER", section_line);
    ++i_;
  }

  /// The next record: "0 TYPE" plus its group codes. Leaves i_ at the following "0" token.
  Record next_record(std::string_view section, std::size_t section_line) {
    if (at_end()) truncated(section, section_line);
    const Token& head = t_[i_];
    if (head.code != 0)
      throw FloorPlanError(line_path(head.line),
                           "expected '0' starting an entity, got group code " + std::to_string(head.code));
    const std::size_t begin = ++i_;
    while (!at_end() && t_[i_].code != 0) ++i_;
    if (at_end()) truncated(section, section_line);
    return Record(head, std::span<const Token>(t_.data() + begin, i_ - begin));
  }

  bool next_is(std::string_view type) const { return !at_end() && t_[i_].code == 0 && trim(t_[i_].value) == type; }

  /// Reads one entity (with its VERTEX / ATTRIB followers) at i_. Returns nullopt for unsupported types and
  /// paper-space entities; `counts`, `skipped` and `paper_space` record them.
  std::optional<Entity> parse_entity(std::string_view section, std::size_t section_line,
                                     std::map<std::string, std::size_t>* counts,
                                     std::map<std::string, std::size_t>& skipped, std::size_t* paper_space) {
    const Record r = next_record(section, section_line);
    const std::string type(trim(r.type()));
    Entity e;
    fill_common(r, e);
    e.type = type;
    const bool in_paper_space = r.integer(67, 0) == 1;
    std::optional<Entity> result;
    if (type == "POLYLINE") {
      result = parse_polyline(r, e, section, section_line);
      if (!result && !in_paper_space) ++skipped["POLYLINE (mesh)"];
    } else if (type == "INSERT") {
      result = parse_insert(r, e, section, section_line);
    } else if (type == "LINE") {
      e.extrusion = extrusion_of(r, e);
      e.shape = Line{required_point(r, 10, e, "start point"), required_point(r, 11, e, "end point")};
      result = std::move(e);
    } else if (type == "ARC" || type == "CIRCLE") {
      e.extrusion = extrusion_of(r, e);
      const auto center = required_point(r, 10, e, "center");
      const double radius = required(r, 40, e, "radius");
      if (!(radius > 0.0)) throw FloorPlanError(e.describe(), "radius must be > 0, got " + std::to_string(radius));
      if (type == "ARC") {
        e.shape = Arc{center, radius, required(r, 50, e, "start angle"), required(r, 51, e, "end angle")};
      } else {
        e.shape = Circle{center, radius};
      }
      result = std::move(e);
    } else if (type == "ELLIPSE") {
      e.extrusion = extrusion_of(r, e);
      Ellipse el{required_point(r, 10, e, "center"), required_point(r, 11, e, "major axis"),
                 required(r, 40, e, "axis ratio"), r.number(41, 0.0), r.number(42, 2.0 * 3.14159265358979323846)};
      if (!(el.major_axis.norm() > 0.0)) throw FloorPlanError(e.describe(), "zero major axis");
      if (!(el.ratio > 0.0)) throw FloorPlanError(e.describe(), "axis ratio must be > 0");
      e.shape = el;
      result = std::move(e);
    } else if (type == "LWPOLYLINE") {
      e.extrusion = extrusion_of(r, e);
      e.shape = parse_lwpolyline(r, e);
      result = std::move(e);
    } else {
      if (!in_paper_space) ++skipped[type];
      // Entities with followers outside POLYLINE/INSERT do not exist in the format; nothing more to consume.
    }
    if (in_paper_space) {
      if (paper_space) ++*paper_space;
      return std::nullopt;
    }
    if (counts) ++(*counts)[type];
    return result;
  }

  std::optional<Entity> parse_polyline(const Record& r, Entity& e, std::string_view section, std::size_t section_line) {
    const int flags = r.integer(70, 0);
    const bool mesh = (flags & (16 | 64)) != 0;
    Polyline p;
    p.closed = (flags & 1) != 0;
    p.is_3d = (flags & 8) != 0;
    p.elevation = r.number(30, 0.0);
    if (!p.is_3d) e.extrusion = extrusion_of(r, e);
    while (next_is("VERTEX")) {
      const Record v = next_record(section, section_line);
      const int vflags = v.integer(70, 0);
      if (mesh || (vflags & 16) != 0) continue;  // mesh vertices; spline frame control points are not on the curve
      Entity ve;
      fill_common(v, ve);
      p.vertices.push_back({{required(v, 10, ve, "vertex x"), required(v, 20, ve, "vertex y")}, v.number(42, 0.0)});
    }
    if (at_end()) truncated(section, section_line);
    if (!next_is("SEQEND")) throw FloorPlanError(e.describe(), "POLYLINE not terminated by SEQEND");
    next_record(section, section_line);
    if (mesh) return std::nullopt;  // polyface and polygon meshes are surfaces, not plan lines
    e.shape = std::move(p);
    return std::move(e);
  }

  std::optional<Entity> parse_insert(const Record& r, Entity& e, std::string_view section, std::size_t section_line) {
    e.extrusion = extrusion_of(r, e);
    Insert ins;
    const auto name = r.text(2);
    if (!name || name->empty()) throw FloorPlanError(e.describe(), "missing block name (group code 2)");
    ins.block = *name;
    ins.insert_point = required_point(r, 10, e, "insertion point");
    ins.scale = {r.number(41, 1.0), r.number(42, 1.0), r.number(43, 1.0)};
    if (ins.scale.x() == 0.0 || ins.scale.y() == 0.0 || ins.scale.z() == 0.0)
      throw FloorPlanError(e.describe(), "zero scale factor (group codes 41/42/43)");
    ins.rotation_deg = r.number(50, 0.0);
    ins.columns = r.integer(70, 1);
    ins.rows = r.integer(71, 1);
    ins.column_spacing = r.number(44, 0.0);
    ins.row_spacing = r.number(45, 0.0);
    if (ins.columns == 0) ins.columns = 1;  // some writers store 0 for "no grid"
    if (ins.rows == 0) ins.rows = 1;
    if (ins.columns < 0 || ins.rows < 0 || static_cast<long long>(ins.columns) * ins.rows > kMaxMinsertCells)
      throw FloorPlanError(e.describe(), "MINSERT grid " + std::to_string(ins.columns) + " x " +
                                             std::to_string(ins.rows) + " is out of range (at most " +
                                             std::to_string(kMaxMinsertCells) + " cells)");
    // Attributes (ATTRIB ... SEQEND) follow when group 66 is 1; they are text, not geometry.
    if (next_is("ATTRIB") || r.integer(66, 0) == 1) {
      while (next_is("ATTRIB")) next_record(section, section_line);
      if (next_is("SEQEND")) next_record(section, section_line);
    }
    e.shape = std::move(ins);
    return std::move(e);
  }

  void parse_entities(Document& doc, std::size_t section_line) {
    while (true) {
      if (at_end()) truncated("ENTITIES", section_line);
      if (at_endsec()) {
        ++i_;
        return;
      }
      if (auto e = parse_entity("ENTITIES", section_line, &doc.entity_counts, doc.skipped_entities,
                                &doc.paper_space_entities))
        doc.entities.push_back(std::move(*e));
    }
  }

  void parse_blocks(Document& doc, std::size_t section_line) {
    while (true) {
      if (at_end()) truncated("BLOCKS", section_line);
      if (at_endsec()) {
        ++i_;
        return;
      }
      const Record head = next_record("BLOCKS", section_line);
      if (trim(head.type()) != "BLOCK")
        throw FloorPlanError(line_path(head.line()), "expected BLOCK, got '" + shorten(head.type()) + "'");
      Block block;
      block.line = head.line();
      const auto name = head.text(2);
      if (!name || name->empty()) throw FloorPlanError(line_path(head.line()), "BLOCK without a name (group code 2)");
      block.name = *name;
      const std::string where = "block " + block.name;
      block.base_point = {head.number(10, 0.0), head.number(20, 0.0), head.number(30, 0.0)};
      while (true) {
        if (at_end()) truncated("BLOCKS", section_line);
        if (next_is("ENDBLK")) {
          next_record("BLOCKS", section_line);
          break;
        }
        if (at_endsec())
          throw FloorPlanError(line_path(t_[i_].line),
                               where + " (line " + std::to_string(block.line) + ") has no ENDBLK");
        std::size_t paper = 0;
        if (auto e = parse_entity("BLOCKS", section_line, nullptr, block.skipped_entities, &paper))
          block.entities.push_back(std::move(*e));
      }
      const auto key = to_upper_ascii(block.name);
      if (doc.blocks.count(key))
        throw FloorPlanError(line_path(block.line), "duplicate definition of block '" + block.name + "'");
      doc.blocks.emplace(key, std::move(block));
    }
  }

  std::vector<Token> t_;
  std::size_t i_ = 0;
};

}  // namespace

std::string Entity::describe() const { return dxf::describe(type, handle, line); }

const Block* Document::find_block(std::string_view name) const {
  auto it = blocks.find(to_upper_ascii(name));
  return it == blocks.end() ? nullptr : &it->second;
}

Document read_dxf(std::string_view text) { return Parser(tokenize(text)).parse(); }

std::optional<double> insunits_to_metres(int insunits) {
  switch (insunits) {
    case 1:
      return 0.0254;  // inch
    case 2:
      return 0.3048;  // foot
    case 3:
      return 1609.344;  // mile
    case 4:
      return 1e-3;  // millimetre
    case 5:
      return 1e-2;  // centimetre
    case 6:
      return 1.0;  // metre
    case 7:
      return 1e3;  // kilometre
    case 8:
      return 0.0254e-6;  // microinch
    case 9:
      return 0.0254e-3;  // mil
    case 10:
      return 0.9144;  // yard
    case 11:
      return 1e-10;  // angstrom
    case 12:
      return 1e-9;  // nanometre
    case 13:
      return 1e-6;  // micron
    case 14:
      return 1e-1;  // decimetre
    case 15:
      return 1e1;  // decametre
    case 16:
      return 1e2;  // hectometre
    case 17:
      return 1e9;  // gigametre
    case 18:
      return 149597870700.0;  // astronomical unit
    case 19:
      return 9460730472580800.0;  // light year
    case 20:
      return 3.0856775814913673e16;  // parsec
    case 21:
      return 1200.0 / 3937.0;  // US survey foot
    case 22:
      return 100.0 / 3937.0;  // US survey inch
    case 23:
      return 3600.0 / 3937.0;  // US survey yard
    case 24:
      return 6336000.0 / 3937.0;  // US survey mile
    default:
      return std::nullopt;
  }
}

std::string insunits_name(int insunits) {
  static const char* const kNames[] = {"unitless",
                                       "inches",
                                       "feet",
                                       "miles",
                                       "millimetres",
                                       "centimetres",
                                       "metres",
                                       "kilometres",
                                       "microinches",
                                       "mils",
                                       "yards",
                                       "angstroms",
                                       "nanometres",
                                       "microns",
                                       "decimetres",
                                       "decametres",
                                       "hectometres",
                                       "gigametres",
                                       "astronomical units",
                                       "light years",
                                       "parsecs",
                                       "US survey feet",
                                       "US survey inches",
                                       "US survey yards",
                                       "US survey miles"};
  if (insunits < 0 || insunits > 24) return "unknown";
  return kNames[insunits];
}

std::string to_upper_ascii(std::string_view text) {
  std::string out(text);
  for (auto& c : out)
    if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  return out;
}

}  // namespace wm::apriori::dxf
