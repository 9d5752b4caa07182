#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include "apriori/floor_plan.h"
#include "apriori/import/import_report.h"
#include "apriori/import/layer_mapping.h"

namespace wm::apriori {

/// Options of import_dxf. Defaults fit an architectural plan in any unit.
struct DxfImportOptions {
  /// Metres per drawing unit, overriding $INSUNITS (e.g. 0.001 for a drawing in millimetres without $INSUNITS).
  std::optional<double> units_to_m;
  /// Metres per drawing unit when $INSUNITS is absent, 0 (unitless) or unknown and there is no override; the
  /// report warns when it is used.
  double unitless_to_m = 1.0;
  /// Largest distance between an arc (ARC, CIRCLE, polyline bulge) and the chords that replace it [m]. Arcs get
  /// at least one chord per 45° whatever the tolerance.
  double arc_tolerance_m = 0.01;
  /// Name of the resulting plan.
  std::string name = "dxf import";
  /// Coordinates beyond limits.max_abs_coordinate_m (after units and block transforms) are absurd: the drawing is
  /// refused. The same limits as for JSON plans, so an imported plan can always be stored and loaded again.
  FloorPlanLimits limits;
  /// Upper bound on the points the drawing may expand to (nested block references multiply) — a guard against
  /// files that would exhaust memory.
  std::size_t max_total_points = 5'000'000;
};

/// Converts an ASCII DXF drawing into a floor plan.
///
/// Model-space LINE, ARC, CIRCLE, ELLIPSE, LWPOLYLINE, POLYLINE (2D and 3D; meshes are skipped) and INSERT are
/// read; curves become chords (options.arc_tolerance_m); every other entity type (TEXT, HATCH, SPLINE, DIMENSION,
/// ...) is skipped and counted in the report.
/// Coordinates are converted to metres ($INSUNITS, or options.units_to_m), and entities with an extrusion
/// direction other than +z are mapped through their object coordinate system, then projected on the plan.
///  - An INSERT whose block name matches a `blocks` rule becomes one object of that kind, posed at the insertion
///    point with the insert's rotation (θ of the block's x axis in the world); its shape, with nested blocks, scale
///    and mirroring applied, is in that frame. Entities of the block on ignored layers are left out.
///  - Other INSERTs are expanded: their entities join the drawing with the insert's transform; entities on block
///    layer "0" take the INSERT's layer (the DXF rule).
///  - Loose entities on a layer whose rule has `cluster` are grouped (LayerMapping::cluster_tolerance_m,
///    merge_enclosed_clusters) into one object per group, posed at its length-weighted centroid with θ = 0.
///  - Entities on other mapped layers become one object each, posed at their centroid with θ = 0.
///  - Entities on ignored layers are skipped; on unmapped layers, they follow mapping.unknown_layers.
/// Object ids are "<kind>-<handle>" (the INSERT's handle for block objects, the first entity's for clusters;
/// "<insert handle>.<entity handle>" for entities of expanded blocks; "L<line>" when the file has no handles).
/// Loading is all or nothing: on any error nothing is returned.
/// @throw FloorPlanError with a path: "line N" for syntax errors and truncated files, the entity ("entity LINE
///        handle 2F") for bad geometry and absurd coordinates, "block A > entity INSERT handle 3C" for a block that
///        inserts itself directly or through others, "layer X" for an unknown layer under policy "error"; binary
///        DXF and DWG files are refused.
/// @throw std::invalid_argument for options out of range (non-positive or non-finite units or tolerance).
ImportResult import_dxf(std::string_view text, const LayerMapping& mapping, const DxfImportOptions& options = {});

}  // namespace wm::apriori
