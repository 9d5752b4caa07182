#!/usr/bin/env python3
"""Prints the vector map held in wmd's shared-memory segment: its version, the counts, and the first elements.

    read_map.py [--server URL | --name wm-...] [--first N]

Without --name it asks the server (GET /api/v1/shm) for the segment, as read_grid.py does.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # worldmodel_shm.py, one directory up

import worldmodel_shm  # noqa: E402

ORIGINS = {0: "client", 1: "scan", 2: "grid", 3: "other"}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--server", default="http://127.0.0.1:8080", help="wmd's URL (default %(default)s)")
    source.add_argument("--name", help="the segment, wm-<uuid> or /dev/shm/wm-<uuid>, instead of asking the server")
    parser.add_argument("--first", type=int, default=5, metavar="N", help="elements and objects to list (default 5)")
    args = parser.parse_args()

    try:
        reader = worldmodel_shm.open_segment(args.name, args.server)
        with reader:
            world_map = reader.read_map()
            truncated = reader.map_truncated
    except worldmodel_shm.ShmError as error:
        print(f"read_map: {error}", file=sys.stderr)
        return 1

    print(f"segment:  {reader.name}{' (map truncated)' if truncated else ''}")
    print(f"version:  {world_map.version}")
    print(f"elements: {len(world_map.elements)}")
    print(f"objects:  {len(world_map.objects)}")
    print(f"edges:    {len(world_map.edges)}")
    for e in world_map.elements[: args.first]:
        print(f"  e{e.number}: ({e.x1:.3f}, {e.y1:.3f}) -> ({e.x2:.3f}, {e.y2:.3f}) m, support {e.support}, "
              f"origin {ORIGINS.get(e.origin, e.origin)}, updated in version {e.updated_version}")
    for o in world_map.objects[: args.first]:
        print(f"  {o.id} ({o.kind}): at ({o.x:.3f}, {o.y:.3f}) m, {o.theta:.3f} rad, {o.edge_count} edges")
    return 0


if __name__ == "__main__":
    sys.exit(main())
