#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace wm::apriori::dxf {

// The low-level model of an ASCII DXF drawing (R12 / AC1009 up to current AutoCAD versions), as written in the
// file: coordinates in drawing units, not yet converted to metres, block references not yet expanded. Only the
// entities that carry plan geometry are kept; every other entity type is counted, not stored.
// The group-code format is described in Autodesk's "DXF Reference" (sections HEADER, BLOCKS, ENTITIES).

/// LINE: both endpoints in the world coordinate system (WCS) of its block [drawing units].
struct Line {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  Eigen::Vector3d end = Eigen::Vector3d::Zero();
};

/// ARC: counter-clockwise in the entity's object coordinate system (OCS, see Entity::extrusion) from start to end
/// angle [deg] around `center` (OCS, z = elevation) [drawing units]. Invariant: radius > 0.
struct Arc {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.0;
  double start_angle_deg = 0.0;
  double end_angle_deg = 0.0;
};

/// CIRCLE: `center` in OCS [drawing units]. Invariant: radius > 0.
struct Circle {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.0;
};

/// ELLIPSE: in WCS (unlike ARC), `major_axis` from the centre to the end of the major axis, minor axis =
/// ratio · (extrusion × major_axis); the curve runs counter-clockwise about the extrusion from start to end
/// parameter [rad] (0 and 2π for a whole ellipse) [drawing units]. Invariant: major_axis ≠ 0, ratio > 0.
struct Ellipse {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d major_axis = Eigen::Vector3d::UnitX();
  double ratio = 1.0;
  double start_param = 0.0;
  double end_param = 0.0;
};

/// A polyline vertex; `bulge` = tan(θ/4) of the arc from this vertex to the next (θ > 0 counter-clockwise in OCS,
/// 0 for a straight segment).
struct PolylineVertex {
  Eigen::Vector2d point = Eigen::Vector2d::Zero();
  double bulge = 0.0;
};

/// LWPOLYLINE, or an old-style 2D/3D POLYLINE with its VERTEX records. 2D polylines are in OCS at `elevation`;
/// a 3D polyline (`is_3d`) is in WCS, no bulges, and its z values are dropped (plans are 2D).
struct Polyline {
  std::vector<PolylineVertex> vertices;
  bool closed = false;
  bool is_3d = false;
  double elevation = 0.0;
};

/// INSERT (or MINSERT when columns/rows > 1): places block `block` with its base point at `insert_point` (OCS),
/// scaled, then rotated counter-clockwise by `rotation_deg` around the insert point. MINSERT cells are offset by
/// (column · column_spacing, row · row_spacing) in the rotated, unscaled insert frame.
struct Insert {
  std::string block;
  Eigen::Vector3d insert_point = Eigen::Vector3d::Zero();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  double rotation_deg = 0.0;
  int columns = 1;
  int rows = 1;
  double column_spacing = 0.0;
  double row_spacing = 0.0;
};

/// One supported entity. `extrusion` is the normal of the entity's plane; with it the "arbitrary axis algorithm"
/// of the DXF Reference gives the OCS → WCS rotation (the identity for (0, 0, 1); a mirror x → −x for (0, 0, −1),
/// which real drawings use for mirrored arcs).
struct Entity {
  std::string type;  // "LINE", "ARC", "CIRCLE", "ELLIPSE", "LWPOLYLINE", "POLYLINE", "INSERT"
  std::string layer = "0";
  std::string handle;                                    // group 5; empty when the file has none (R12 without handles)
  std::size_t line = 0;                                  // 1-based line of the entity's "0" group code in the file
  Eigen::Vector3d extrusion = Eigen::Vector3d::UnitZ();  // unit length
  std::variant<Line, Arc, Circle, Ellipse, Polyline, Insert> shape;

  /// "entity LINE handle 2F", or "entity LINE at line 1234" when the entity has no handle: the path of errors.
  std::string describe() const;
};

/// A BLOCK definition: entities in block coordinates; an INSERT maps `base_point` to its insertion point.
struct Block {
  std::string name;  // as written in the file; look-ups are case-insensitive (AutoCAD names are)
  Eigen::Vector3d base_point = Eigen::Vector3d::Zero();
  std::size_t line = 0;
  std::vector<Entity> entities;
  std::map<std::string, std::size_t> skipped_entities;  // unsupported entity types inside the block → count
};

/// A parsed drawing.
struct Document {
  std::string version;                  // $ACADVER, e.g. "AC1009" (R12), "AC1027" (R2013); empty when absent
  std::optional<int> insunits;          // $INSUNITS (0 = unitless, 4 = mm, 6 = m, ...; see insunits_to_metres)
  std::vector<Entity> entities;         // model space, in file order (paper-space entities are left out)
  std::map<std::string, Block> blocks;  // key: block name in upper case
  std::map<std::string, std::size_t> entity_counts;     // every model-space entity by type, supported or not
  std::map<std::string, std::size_t> skipped_entities;  // model-space entities of unsupported types, by type
  std::size_t paper_space_entities = 0;

  /// The block called `name` (case-insensitive), or nullptr.
  const Block* find_block(std::string_view name) const;
};

/// Parses the text of an ASCII DXF file (LF or CRLF line endings). Strings are returned as UTF-8: \U+XXXX escapes
/// are decoded and text that is not valid UTF-8 (pre-2007 files in a Windows code page) is read as Latin-1.
/// @throw FloorPlanError (apriori/floor_plan.h) with path "line N" (syntax: a group code that is not an integer,
///        a number that does not parse or is not finite, a truncated file, a missing EOF or ENDSEC) or the
///        entity's describe() (a missing coordinate, a radius ≤ 0, a zero scale); binary DXF and DWG files are
///        refused with a message that says so.
Document read_dxf(std::string_view text);

/// Metres per drawing unit for a $INSUNITS code (1 inch, 2 foot, 4 mm, 5 cm, 6 m, ... 24 US survey mile);
/// nullopt for 0 (unitless) and unknown codes.
std::optional<double> insunits_to_metres(int insunits);

/// A readable name for a $INSUNITS code ("millimetres", ...; "unitless" for 0, "unknown" otherwise).
std::string insunits_name(int insunits);

/// Upper-cases ASCII letters (DXF layer and block names compare case-insensitively).
std::string to_upper_ascii(std::string_view text);

}  // namespace wm::apriori::dxf
