#!/usr/bin/env python3
"""The demo building as built, for a simulated drive: the demo plan's walls and tables with a few changes.

- demolished: the thick wall between GDC1's main corridor and the room north of it at x 10.5-14.2 m (its two faces,
  wall-176 and wall-178, and its east end, wall-179);
- built: a 3 m partition in that room, from (11.5, 12.5) to (14.5, 12.5);
- moved: table-3 by (0.3 m, 0.2 m, 10 degrees).
Writes the building as an AMRL vector map (a JSON list of {"p0": {"x", "y"}, "p1": {"x", "y"}}), which
wm-raycast-log drives a laser through. Usage: make_demo_building.py demo-plan.json > building.json
"""
import json
import math
import sys

DEMOLISHED = {"wall-176", "wall-178", "wall-179"}
PARTITIONS = [((11.5, 12.5), (14.5, 12.5))]
MOVED = {"table-3": (0.3, 0.2, math.radians(10))}


def placed(pose, point):
    c, s = math.cos(pose["theta"]), math.sin(pose["theta"])
    return (pose["x"] + c * point[0] - s * point[1], pose["y"] + s * point[0] + c * point[1])


def line(a, b):
    return {"p0": {"x": a[0], "y": a[1]}, "p1": {"x": b[0], "y": b[1]}}


def main(path):
    with open(path) as f:
        plan = json.load(f)
    lines = []
    for obj in plan["objects"]:
        if obj["id"] in DEMOLISHED:
            continue
        pose = dict(obj.get("pose", {"x": 0, "y": 0, "theta": 0}))
        if obj["id"] in MOVED:
            dx, dy, dtheta = MOVED[obj["id"]]
            pose = {"x": pose["x"] + dx, "y": pose["y"] + dy, "theta": pose["theta"] + dtheta}
        for polyline in obj.get("segments", []):
            for a, b in zip(polyline, polyline[1:]):
                lines.append(line(placed(pose, a), placed(pose, b)))
        ring = obj.get("polygon", [])
        for i, a in enumerate(ring):
            lines.append(line(placed(pose, a), placed(pose, ring[(i + 1) % len(ring)])))
    for a, b in PARTITIONS:
        lines.append(line(a, b))
    json.dump(lines, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1])
