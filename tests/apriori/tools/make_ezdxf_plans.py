#!/usr/bin/python3
"""Writes DXF test drawings with ezdxf (an independent DXF implementation) and, for each, the geometry ezdxf
itself reads back from the drawing, in metres, as JSON. The C++ test (ezdxf_plans_test.cpp) imports the drawings
with wm::apriori::import_dxf and compares (1e-9 relative).

Usage: make_ezdxf_plans.py OUTDIR

For every case OUTDIR gets <case>.dxf and <case>.expected.json:
  {"dxf": file, "mapping": file, "units_to_m": override or null, "metres_per_unit": f, "insunits": n,
   "version": "AC1009",
   "entity_counts": {type: n}, "skipped": {type: n}, "unknown_layers": [...], "block_objects": n,
   "objects": {id: {"kind", "attributes", "pose": {"x","y","theta"} or null, "paths": [[primitive, ...], ...]}}}
A path is one polyline of the object, as ezdxf's primitives in world coordinates [m]:
  {"type": "line", "start", "end"}
  {"type": "arc", "center", "radius", "start", "end", "sweep"}     sweep [rad], signed (counter-clockwise > 0)
  {"type": "circle", "center", "radius", "sweep"}
  {"type": "ellipse", "center", "major", "minor", "start", "end", "sweep"}   sweep of the ellipse parameter
Ids follow the importer's documented rule: "<kind>-<handle>", "<kind>-<insert handle>.<entity handle>" inside
expanded blocks, "_r<row>c<col>" after the handle of a MINSERT cell. Kinds come from the mapping written here,
looked up by exact layer / block name (the mapping's patterns are exact names, except "TABLE*" and "SKIP*").
Exits with status 1 when ezdxf cannot be imported: the test must fail, not skip.
"""
import json
import math
import os
import sys

try:
    import ezdxf
    from ezdxf import units as ezunits
    from ezdxf.math import Vec3, arc_angle_span_deg
except ImportError as e:  # pragma: no cover
    print(f"make_ezdxf_plans.py: python3-ezdxf is required ({e})", file=sys.stderr)
    sys.exit(1)

SUPPORTED = {"LINE", "ARC", "CIRCLE", "ELLIPSE", "LWPOLYLINE", "POLYLINE", "INSERT"}

MAPPING = {
    "layers": {
        "LINES": {"kind": "line", "attributes": ["solid"]},
        "ARCS": {"kind": "arc"},
        "CIRCLES": {"kind": "circle"},
        "POLYS": {"kind": "poly", "attributes": ["solid", "glass"]},
        "BLOCKS": {"kind": "part"},
        "FURN": {"kind": "furniture", "attributes": ["not_deformable"], "cluster": True},
        "IGNORED": {"ignore": True},
        "0": {"ignore": True},
    },
    "blocks": {
        "TABLE*": {"kind": "table", "attributes": ["not_deformable"]},
        "SKIP*": {"ignore": True},
    },
    "cluster_tolerance_m": 0.02,
    "unknown_layers": "report",
}


def layer_rule(layer):
    return MAPPING["layers"].get(layer.upper()) or MAPPING["layers"].get(layer)


def block_rule(name):
    if name.upper().startswith("TABLE"):
        return MAPPING["blocks"]["TABLE*"]
    if name.upper().startswith("SKIP"):
        return MAPPING["blocks"]["SKIP*"]
    return None


def xy(v, f):
    return [v[0] * f, v[1] * f]


def primitives(e, f):
    """The entity (in WCS, already transformed) as a list of paths of primitives, scaled by f [m per unit]."""
    t = e.dxftype()
    if t == "LINE":
        return [[{"type": "line", "start": xy(e.dxf.start, f), "end": xy(e.dxf.end, f)}]]
    if t == "ARC":
        ocs = e.ocs()
        span = math.radians(arc_angle_span_deg(e.dxf.start_angle, e.dxf.end_angle))
        sign = 1.0 if ocs.uz.z > 0 else -1.0
        return [[{"type": "arc", "center": xy(ocs.to_wcs(e.dxf.center), f), "radius": e.dxf.radius * f,
                  "start": xy(e.start_point, f), "end": xy(e.end_point, f), "sweep": sign * span}]]
    if t == "CIRCLE":
        ocs = e.ocs()
        sign = 1.0 if ocs.uz.z > 0 else -1.0
        return [[{"type": "circle", "center": xy(ocs.to_wcs(e.dxf.center), f), "radius": e.dxf.radius * f,
                  "sweep": sign * 2 * math.pi}]]
    if t == "ELLIPSE":
        span = (e.dxf.end_param - e.dxf.start_param) % (2 * math.pi)
        if span == 0:
            span = 2 * math.pi
        return [[{"type": "ellipse", "center": xy(e.dxf.center, f), "major": xy(e.dxf.major_axis, f),
                  "minor": xy(e.minor_axis, f), "start": xy(e.start_point, f), "end": xy(e.end_point, f),
                  "sweep": span}]]
    if t in ("LWPOLYLINE", "POLYLINE"):
        # ezdxf explodes a polyline into LINE and ARC entities; an ARC always runs counter-clockwise, so a
        # clockwise bulge comes out reversed: orient every primitive along the polyline.
        path = []
        for ve in e.virtual_entities():
            for p in primitives(ve, f):
                path.extend(p)
        if t == "LWPOLYLINE":
            at = xy(next(iter(e.vertices_in_wcs())), f)
        elif e.is_3d_polyline:
            at = xy(e.vertices[0].dxf.location, f)
        else:
            at = xy(e.ocs().to_wcs(e.vertices[0].dxf.location.replace(z=e.dxf.elevation.z)), f)
        for prim in path:
            if math.dist(prim["start"], at) > math.dist(prim["end"], at):
                prim["start"], prim["end"] = prim["end"], prim["start"]
                if "sweep" in prim:
                    prim["sweep"] = -prim["sweep"]
            at = prim["end"]
        return [path]
    raise ValueError(f"unexpected entity {t}")


class Expectation:
    def __init__(self, doc, f):
        self.doc = doc
        self.f = f
        self.objects = {}
        self.block_objects = 0
        self.unknown = set()

    def add(self, oid, kind, attributes, paths, pose=None):
        assert oid not in self.objects, oid
        self.objects[oid] = {"kind": kind, "attributes": attributes, "pose": pose, "paths": paths}

    def block_paths(self, insert, layer):
        """Every primitive of a mapped block insert (nested inserts expanded), skipping ignored layers.
        layer: the insert's effective layer, inherited by block entities on layer "0"."""
        paths = []
        block = self.doc.blocks[insert.dxf.name]
        for src, ve in zip(block, insert.virtual_entities()):
            eff = src.dxf.layer if src.dxf.layer != "0" else layer
            rule = layer_rule(eff)
            if rule and rule.get("ignore"):
                continue
            if ve.dxftype() == "INSERT":
                for cell in ve.multi_insert():
                    paths += self.block_paths(cell, eff)
            else:
                paths += primitives(ve, self.f)
        return paths

    def pose(self, insert):
        m = insert.matrix44()
        base = self.doc.blocks[insert.dxf.name].block.dxf.base_point
        o = m.transform(base)
        x = m.transform_direction(Vec3(1, 0, 0))
        return {"x": o.x * self.f, "y": o.y * self.f, "theta": math.atan2(x.y, x.x)}

    def entity(self, e, src, prefix, layer):
        """e: the entity in WCS; src: the entity as stored (for its handle); layer: the effective layer."""
        t = e.dxftype()
        if t not in SUPPORTED:
            return  # skipped and counted by type
        rule = layer_rule(layer)
        key = prefix + src.dxf.handle
        if t == "INSERT":
            if rule and rule.get("ignore"):
                return
            brule = block_rule(e.dxf.name)
            if brule and brule.get("ignore"):
                return
            cells = list(e.multi_insert())
            grid = e.dxf.row_count * e.dxf.column_count > 1
            for i, cell in enumerate(cells):
                row, col = divmod(i, e.dxf.column_count)
                cell_key = key + (f"_r{row + 1}c{col + 1}" if grid else "")
                if brule:
                    self.add(f"{brule['kind']}-{cell_key}", brule["kind"], brule.get("attributes", []),
                             self.block_paths(cell, layer), self.pose(cell))
                    self.block_objects += 1
                else:
                    block = self.doc.blocks[e.dxf.name]
                    for bsrc, ve in zip(block, cell.virtual_entities()):
                        self.entity(ve, bsrc, cell_key + ".", bsrc.dxf.layer if bsrc.dxf.layer != "0" else layer)
            return
        if rule is None:
            self.unknown.add(layer)
            return
        if rule.get("ignore") or rule.get("cluster"):
            return  # clusters are described by the case itself
        if t == "LINE" and e.dxf.start.isclose(e.dxf.end):
            return  # degenerate
        self.add(f"{rule['kind']}-{key}", rule["kind"], rule.get("attributes", []), primitives(e, self.f))


def counts(msp):
    result = {}
    for e in msp:
        result[e.dxftype()] = result.get(e.dxftype(), 0) + 1
    return result


def write_case(outdir, name, doc, units_to_m=None, clusters=None, dxf_only=False):
    path = os.path.join(outdir, name + ".dxf")
    doc.saveas(path)
    if dxf_only:
        return
    doc = ezdxf.readfile(path)  # expectations from what ezdxf reads back, not from what we meant to write
    insunits = doc.header.get("$INSUNITS", 0)
    if units_to_m is not None:
        f = units_to_m
    elif ezunits.METER_FACTOR[insunits] is None:
        f = 1.0  # unitless (R12 has no $INSUNITS): the importer's documented default, metres
    else:
        f = 1.0 / ezunits.METER_FACTOR[insunits]
    msp = doc.modelspace()
    ex = Expectation(doc, f)
    for e in msp:
        ex.entity(e, e, "", e.dxf.layer)
    for members in clusters or []:
        paths = []
        for handle in members:
            paths += primitives(doc.entitydb[handle], f)
        rule = layer_rule(doc.entitydb[members[0]].dxf.layer)
        ex.add(f"{rule['kind']}-{members[0]}", rule["kind"], rule.get("attributes", []), paths)
    c = counts(msp)
    expected = {
        "dxf": name + ".dxf",
        "mapping": "mapping.json",
        "units_to_m": units_to_m,
        "metres_per_unit": f,
        "insunits": insunits,
        "version": doc.dxfversion,
        "entity_counts": c,
        "skipped": {t: n for t, n in c.items() if t not in SUPPORTED},
        "unknown_layers": sorted(ex.unknown),
        "block_objects": ex.block_objects,
        "clustered_objects": len(clusters or []),
        "objects": ex.objects,
    }
    with open(os.path.join(outdir, name + ".expected.json"), "w") as out:
        json.dump(expected, out, indent=1)


def define_blocks(doc, lw):
    """TABLE_A (mapped), SUB and ASSEMBLY (expanded; ASSEMBLY nests SUB and TABLE_A), SKIP_ME (ignored)."""
    table = doc.blocks.new("TABLE_A", base_point=(0.5, 0.25))
    outline = [(0, 0), (1.2, 0), (1.2, 0.8), (0, 0.8)]
    if lw:
        table.add_lwpolyline(outline, format="xy", close=True, dxfattribs={"layer": "0"})
    else:
        table.add_polyline2d(outline, close=True, dxfattribs={"layer": "0"})
    table.add_circle((0.6, 0.4), 0.2, dxfattribs={"layer": "0"})
    table.add_arc((0.6, 0.4), 0.35, 200, 340, dxfattribs={"layer": "0"})
    table.add_line((0.1, 0.1), (0.3, 0.1), dxfattribs={"layer": "IGNORED"})  # left out of the object

    sub = doc.blocks.new("SUB", base_point=(0, 0))
    sub.add_line((0, 0), (1, 0.5), dxfattribs={"layer": "0"})
    sub.add_circle((0.5, -0.5), 0.25, dxfattribs={"layer": "LINES"})

    asm = doc.blocks.new("ASSEMBLY", base_point=(1, 1))
    asm.add_line((1, 1), (3, 1), dxfattribs={"layer": "0"})
    asm.add_arc((2, 2), 1.0, 0, 90, dxfattribs={"layer": "ARCS"})
    asm.add_blockref("SUB", (3, 3), dxfattribs={"layer": "0", "rotation": -30, "xscale": 0.5, "yscale": 0.5})
    asm.add_blockref("TABLE_A", (0, 4), dxfattribs={"layer": "0", "rotation": 90})
    skip = doc.blocks.new("SKIP_ME")
    skip.add_line((0, 0), (1, 1))


def geometry_doc(version, insunits=6):
    doc = ezdxf.new(version)
    doc.header["$INSUNITS"] = insunits
    lw = version != "R12"
    for name in ("LINES", "ARCS", "CIRCLES", "POLYS", "BLOCKS", "FURN", "IGNORED", "MYSTERY"):
        doc.layers.add(name)
    define_blocks(doc, lw)
    msp = doc.modelspace()
    msp.add_line((0, 0), (10, 0), dxfattribs={"layer": "LINES"})
    msp.add_line((1.5, 2.25), (-3.125, 7.75), dxfattribs={"layer": "LINES"})
    msp.add_line((4, 4), (4, 4), dxfattribs={"layer": "LINES"})  # zero length: skipped
    msp.add_arc((5, 5), 2, 30, 120, dxfattribs={"layer": "ARCS"})
    msp.add_arc((5, 5), 3, 300, 45, dxfattribs={"layer": "ARCS"})  # through 0°
    msp.add_arc((3, 4), 1.5, 10, 100, dxfattribs={"layer": "ARCS", "extrusion": (0, 0, -1)})  # mirrored
    msp.add_circle((20, 5), 0.75, dxfattribs={"layer": "CIRCLES"})
    msp.add_circle((4, 2), 0.3, dxfattribs={"layer": "CIRCLES", "extrusion": (0, 0, -1)})
    msp.add_polyline2d([(0, 10, 0, 0, 0.5), (4, 10, 0, 0, -1.2), (6, 12, 0, 0, 0), (9, 12, 0, 0, 0)],
                       format="xyseb", dxfattribs={"layer": "POLYS"})
    msp.add_polyline2d([(20, 20, 0, 0, 0), (22, 20, 0, 0, 1.0), (22, 21, 0, 0, 0), (20, 21, 0, 0, 0.25)],
                       format="xyseb", close=True, dxfattribs={"layer": "POLYS"})
    msp.add_polyline3d([(30, 0, 1), (31, 1, 2), (33, 1, 0)], dxfattribs={"layer": "POLYS"})
    if lw:
        msp.add_lwpolyline([(0, 15, 0, 0, 0.5), (4, 15, 0, 0, -1.2), (6, 17, 0, 0, 0), (9, 17, 0, 0, 0)],
                           format="xyseb", dxfattribs={"layer": "POLYS"})
        msp.add_lwpolyline([(10, 15, 0, 0, 0), (12, 15, 0, 0, 0.4142135623730951), (12, 16, 0, 0, 0),
                            (10, 16, 0, 0, -3.0)], format="xyseb", close=True, dxfattribs={"layer": "POLYS"})
        msp.add_lwpolyline([(1, 1, 0, 0, 0.3), (2, 1, 0, 0, 0), (2, 2, 0, 0, 0)], format="xyseb",
                           dxfattribs={"layer": "POLYS", "extrusion": (0, 0, -1), "elevation": 0.5})
        msp.add_ellipse((30, -5), major_axis=(2, 1), ratio=0.4, start_param=0.3, end_param=4.0,
                        dxfattribs={"layer": "ARCS"})
        msp.add_ellipse((35, -5), major_axis=(0, 1.5), ratio=0.5, start_param=5.5, end_param=1.0,
                        dxfattribs={"layer": "ARCS", "extrusion": (0, 0, -1)})
        msp.add_ellipse((40, -5), major_axis=(1, 0), ratio=0.25, dxfattribs={"layer": "CIRCLES"})  # whole
    # Mapped block: rotated and scaled, mirrored, OCS -z, non-uniform (its arcs become ellipses), MINSERT grid.
    msp.add_blockref("TABLE_A", (12, 3), dxfattribs={"layer": "BLOCKS", "rotation": 30, "xscale": 1.5,
                                                       "yscale": 1.5, "zscale": 1.5})
    msp.add_blockref("TABLE_A", (15, -2), dxfattribs={"layer": "BLOCKS", "rotation": 200, "xscale": -1})
    msp.add_blockref("TABLE_A", (18, 2), dxfattribs={"layer": "BLOCKS", "rotation": 10,
                                                      "extrusion": (0, 0, -1)})
    msp.add_blockref("TABLE_A", (25, 8), dxfattribs={"layer": "BLOCKS", "rotation": 45, "xscale": 2,
                                                      "yscale": 0.5})
    grid = msp.add_blockref("TABLE_A", (30, 10), dxfattribs={"layer": "BLOCKS", "rotation": 15})
    grid.dxf.column_count = 2
    grid.dxf.row_count = 3
    grid.dxf.column_spacing = 3
    grid.dxf.row_spacing = 2
    # Expanded block with nesting (SUB inside ASSEMBLY, TABLE_A inside ASSEMBLY), layer-0 inheritance.
    msp.add_blockref("ASSEMBLY", (40, 5), dxfattribs={"layer": "BLOCKS", "rotation": 45, "xscale": 2,
                                                       "yscale": 2, "zscale": 2})
    msp.add_blockref("ASSEMBLY", (50, -5), dxfattribs={"layer": "BLOCKS", "rotation": -120, "xscale": 0.5,
                                                        "yscale": -0.5})
    msp.add_blockref("TABLE_A", (0, -10), dxfattribs={"layer": "IGNORED"})  # ignored layer: nothing
    msp.add_blockref("SKIP_ME", (0, -12), dxfattribs={"layer": "BLOCKS"})  # ignored block: nothing
    msp.add_line((100, 100), (101, 101), dxfattribs={"layer": "MYSTERY"})  # unknown layer: reported
    return doc


def cluster_doc():
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4  # millimetres
    doc.layers.add("FURN")
    msp = doc.modelspace()
    clusters = []
    for k in range(3):  # three chairs: a 600 mm square of touching lines, a backrest arc, two loose buttons
        x0 = 3000.0 * k
        a = dict(layer="FURN")
        members = [msp.add_line((x0, 0), (x0 + 600, 0), dxfattribs=a).dxf.handle,
                   msp.add_line((x0 + 600, 0), (x0 + 600, 600), dxfattribs=a).dxf.handle,
                   msp.add_line((x0 + 600, 600), (x0, 600), dxfattribs=a).dxf.handle,
                   msp.add_line((x0, 600), (x0, 0), dxfattribs=a).dxf.handle,
                   msp.add_arc((x0 + 300, 600), 300, 0, 180, dxfattribs=a).dxf.handle,
                   msp.add_circle((x0 + 200, 300), 15, dxfattribs=a).dxf.handle,
                   msp.add_circle((x0 + 400, 300), 15, dxfattribs=a).dxf.handle]
        clusters.append(members)
    # A table outline and a line 10 mm from it (within the 20 mm tolerance): one object.
    table = msp.add_lwpolyline([(20000, 0), (21200, 0), (21200, 800), (20000, 800)], format="xy", close=True,
                               dxfattribs={"layer": "FURN"})
    near = msp.add_line((20100, 810), (20500, 810), dxfattribs={"layer": "FURN"})
    clusters.append([table.dxf.handle, near.dxf.handle])
    lone = msp.add_line((25000, 0), (25000, 500), dxfattribs={"layer": "FURN"})  # 500 mm away: alone
    clusters.append([lone.dxf.handle])
    return doc, clusters


def unknown_entities_doc():
    doc = ezdxf.new("R2018")
    doc.header["$INSUNITS"] = 6
    doc.layers.add("LINES")
    msp = doc.modelspace()
    a = {"layer": "LINES"}
    msp.add_line((0, 0), (1, 0), dxfattribs=a)
    msp.add_text("hello", dxfattribs=a)
    msp.add_mtext("multi\\Pline", dxfattribs=a)
    msp.add_point((1, 1), dxfattribs=a)
    msp.add_spline([(0, 0), (1, 2), (3, 1), (4, 4)], dxfattribs=a)
    msp.add_ellipse((5, 5), major_axis=(2, 0), ratio=0.5, dxfattribs=a)
    msp.add_solid([(0, 0), (1, 0), (0, 1)], dxfattribs=a)
    hatch = msp.add_hatch(color=2, dxfattribs=a)
    hatch.paths.add_polyline_path([(0, 0), (1, 0), (1, 1)], is_closed=True)
    dim = msp.add_linear_dim(base=(0, 2), p1=(0, 0), p2=(3, 0), dxfattribs=a)
    dim.render()
    msp.add_line((0, 1), (1, 1), dxfattribs=a)
    return doc


def main(outdir):
    os.makedirs(outdir, exist_ok=True)
    with open(os.path.join(outdir, "mapping.json"), "w") as out:
        json.dump(MAPPING, out, indent=1)
    for version in ("R12", "R2000", "R2010", "R2018"):
        write_case(outdir, "geometry_" + version.lower(), geometry_doc(version))
    for unit_name, code in (("in", 1), ("ft", 2), ("mm", 4), ("cm", 5), ("dm", 14)):
        write_case(outdir, "units_" + unit_name, geometry_doc("R2010", code))
    write_case(outdir, "units_override", geometry_doc("R2010", 0), units_to_m=0.001)
    doc, clusters = cluster_doc()
    write_case(outdir, "clusters", doc, clusters=clusters)
    write_case(outdir, "unknown_entities", unknown_entities_doc())
    binary = geometry_doc("R2010")
    binary.saveas(os.path.join(outdir, "binary.dxf"), fmt="bin")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    main(sys.argv[1])
