#!/usr/bin/python3
"""Counts the real plans in tests/data/plans independently of the C++ importers (ezdxf for the DXF, PyYAML for
the Open-RMF building, plain json for the AMRL maps) and prints the numbers real_plans_test.cpp expects.

Usage: /usr/bin/python3 count_real_plans.py [tests/data/plans]

Clusters are counted with the rule documented in apriori/import/layer_mapping.h, implemented here from scratch on
ezdxf's own flattening of arcs (sagitta 0.1 mm): entities connected when their curves come within 0.02 m, then a
group inside the bounding box (grown by 0.02 m) of a larger group joins the smallest such group.
"""
import collections
import json
import math
import os
import sys

import ezdxf
from ezdxf import bbox
import yaml

TOL = 0.02


def flat(e):
    t = e.dxftype()
    if t == "LINE":
        return [(e.dxf.start.x, e.dxf.start.y), (e.dxf.end.x, e.dxf.end.y)]
    return [(p.x, p.y) for p in e.flattening(1e-4)]


def point_segment(p, a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    l2 = dx * dx + dy * dy
    t = 0.0 if l2 == 0 else max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / l2))
    return math.hypot(a[0] + t * dx - p[0], a[1] + t * dy - p[1])


def orient(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def segment_distance(a, b, c, d):
    d1, d2, d3, d4 = orient(c, d, a), orient(c, d, b), orient(a, b, c), orient(a, b, d)
    if d1 * d2 < 0 and d3 * d4 < 0:
        return 0.0
    return min(point_segment(a, c, d), point_segment(b, c, d), point_segment(c, a, b), point_segment(d, a, b))


def box(points):
    xs = [p[0] for p in points]
    ys = [p[1] for p in points]
    return min(xs), min(ys), max(xs), max(ys)


def clusters(entities):
    polys = [flat(e) for e in entities]
    boxes = [box(p) for p in polys]
    parent = list(range(len(polys)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(len(polys)):
        for j in range(i + 1, len(polys)):
            a, b = boxes[i], boxes[j]
            if a[0] > b[2] + TOL or b[0] > a[2] + TOL or a[1] > b[3] + TOL or b[1] > a[3] + TOL:
                continue
            if find(i) == find(j):
                continue
            if any(segment_distance(p, q, r, s) <= TOL for p, q in zip(polys[i], polys[i][1:])
                   for r, s in zip(polys[j], polys[j][1:])):
                parent[find(i)] = find(j)
    groups = collections.defaultdict(list)
    for i in range(len(polys)):
        groups[find(i)].append(i)
    gbox = {g: box([p for i in m for p in polys[i]]) for g, m in groups.items()}
    area = {g: (b[2] - b[0]) * (b[3] - b[1]) for g, b in gbox.items()}
    up = {}
    for a in groups:
        A = gbox[a]
        best = None
        for b in groups:
            B = gbox[b]
            if area[b] > area[a] and B[0] - TOL <= A[0] and B[1] - TOL <= A[1] and B[2] + TOL >= A[2] \
                    and B[3] + TOL >= A[3] and (best is None or area[b] < area[best]):
                best = b
        up[a] = best
    roots = set()
    for a in groups:
        while up[a] is not None:
            a = up[a]
        roots.add(a)
    return len(groups), len(roots)


def barcelona(path):
    doc = ezdxf.readfile(path)
    msp = doc.modelspace()
    by_type = collections.Counter(e.dxftype() for e in msp)
    by_layer = collections.Counter(e.dxf.layer for e in msp)
    zero = sum(1 for e in msp if e.dxftype() == "LINE" and e.dxf.start.isclose(e.dxf.end, abs_tol=1e-6))
    result = {"version": doc.dxfversion, "insunits": doc.header.get("$INSUNITS"), "types": dict(by_type),
              "layers": dict(by_layer), "zero_length_lines": zero, "clusters": {}}
    for layer in ("Furniture", "Doors", "Columns"):
        touching, final = clusters([e for e in msp if e.dxf.layer == layer])
        result["clusters"][layer] = {"touching_groups": touching, "objects": final}
    imported = [e for e in msp if e.dxf.layer in ("Walls", "Columns", "Crystal", "Doors", "Furniture")]
    ext = bbox.extents(imported)
    result["imported_extent"] = [ext.extmin.x, ext.extmin.y, ext.extmax.x, ext.extmax.y]
    ext = bbox.extents(msp)
    result["drawing_extent"] = [ext.extmin.x, ext.extmin.y, ext.extmax.x, ext.extmax.y]
    return result


def rmf(path):
    with open(path) as f:
        doc = yaml.safe_load(f)
    level = doc["levels"]["L1"]
    v = [(p[0], p[1]) for p in level["vertices"]]
    scales = [m[2]["distance"][1] / math.dist(v[m[0]], v[m[1]]) for m in level["measurements"]]
    s = sum(scales) / len(scales)

    def world(p):
        return p[0] * s, -p[1] * s

    points = []
    for w in level["walls"] + level["doors"]:
        points += [world(v[w[0]]), world(v[w[1]])]
    static = [m for m in level["models"] if m.get("static", True)]
    for m in static:
        x, y = world((m["x"], m["y"]))
        c, sn = math.cos(m["yaw"]), math.sin(m["yaw"])
        for dx, dy in ((-0.25, -0.25), (0.25, -0.25), (0.25, 0.25), (-0.25, 0.25)):
            points.append((x + c * dx - sn * dy, y + sn * dx + c * dy))
    glass = sum(1 for w in level["walls"] if w[2].get("alpha", [3, 1.0])[1] < 1.0)
    return {"vertices": len(v), "walls": len(level["walls"]), "doors": len(level["doors"]),
            "models": len(level["models"]), "static_models": len(static), "floors": len(level["floors"]),
            "lanes": len(level["lanes"]), "measurements": len(level["measurements"]), "metres_per_pixel": s,
            "glass_walls": glass, "extent": list(box(points)),
            "door_names": [d[2]["name"][1] for d in level["doors"]]}


def amrl(path):
    with open(path) as f:
        segments = json.load(f)
    kept = [s for s in segments
            if math.dist((s["p0"]["x"], s["p0"]["y"]), (s["p1"]["x"], s["p1"]["y"])) >= 1e-3]
    points = [(s[k]["x"], s[k]["y"]) for s in kept for k in ("p0", "p1")]
    return {"segments": len(segments), "kept": len(kept), "extent": list(box(points))}


def main(folder):
    print(json.dumps({
        "barcelona-pavilion.dxf": barcelona(os.path.join(folder, "barcelona-pavilion.dxf")),
        "rmf-office.building.yaml": rmf(os.path.join(folder, "rmf-office.building.yaml")),
        "GDC1.vectormap.json": amrl(os.path.join(folder, "GDC1.vectormap.json")),
        "AHG2.vectormap.json": amrl(os.path.join(folder, "AHG2.vectormap.json")),
    }, indent=1))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "../../data/plans"))
