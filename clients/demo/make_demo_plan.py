#!/usr/bin/env python3
"""Turns an AMRL vector map (JSON list of wall segments, metres) into a worldmodel floor plan.

Every wall segment becomes a `wall` object with the `solid` attribute; three tables (`not_deformable`)
are placed in open space so that the demo can show rigid adjustments (table-3 stands in the room north of the
corridor, where make_demo_building.py moves it).
Usage: make_demo_plan.py GDC1.vectormap.json > plan.json
"""
import json
import math
import sys


def main(path):
    with open(path) as f:
        segments = json.load(f)
    objects = []
    for i, s in enumerate(segments):
        p0 = [s["p0"]["x"], s["p0"]["y"]]
        p1 = [s["p1"]["x"], s["p1"]["y"]]
        if math.dist(p0, p1) < 1e-3:
            continue  # the source has a few zero-length strokes; they are not walls
        objects.append({"id": f"wall-{i}", "kind": "wall", "attributes": ["solid"],
                        "pose": {"x": 0, "y": 0, "theta": 0}, "segments": [[p0, p1]]})
    table = [[-0.6, -0.4], [0.6, -0.4], [0.6, 0.4], [-0.6, 0.4]]
    objects.append({"id": "table-1", "kind": "table", "attributes": ["not_deformable"],
                    "pose": {"x": 0.0, "y": 0.0, "theta": 0.3}, "polygon": table})
    objects.append({"id": "table-2", "kind": "table", "attributes": ["not_deformable"],
                    "pose": {"x": 3.0, "y": -2.0, "theta": 0.0}, "polygon": table})
    objects.append({"id": "table-3", "kind": "table", "attributes": ["not_deformable"],
                    "pose": {"x": 12.5, "y": 11.2, "theta": 0.0}, "polygon": table})
    json.dump({"name": "GDC1 (UT Austin AMRL vector map) + demo tables", "units": "m", "objects": objects},
              sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
