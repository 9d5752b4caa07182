#!/usr/bin/env python3
"""Prints what wmd's shared-memory segment holds of one grid layer, and optionally writes it as a PGM image.

    read_grid.py [--server URL | --name wm-...] [--layer bayes] [--pgm out.pgm]

Without --name it asks the server (GET /api/v1/shm) for the segment's name, and asks again when that name is gone
by the time it is opened (the server grew the segment); the segment must be on this machine. A retired segment's
successor is followed.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # worldmodel_shm.py, one directory up

import worldmodel_shm  # noqa: E402

OCCUPIED = 0.65  # p above this counts as occupied (map_server's occupied_thresh)
UNKNOWN_PIXEL = 205  # map_server's grey for unknown cells


def write_pgm(path: str, dense: worldmodel_shm.Dense, layer: str) -> None:
    """P5, 255 = free (white), 0 = occupied, 205 = unknown; the image's top row is the grid's highest row.

    The same pixels as GET /api/v1/grid?format=pgm.
    """
    if worldmodel_shm.HAVE_NUMPY:
        import numpy as np

        grid = dense.values.reshape(dense.height, dense.width)[::-1].astype(np.float64)  # double, as the server
        shade = np.floor(255.0 * (1.0 - np.clip(grid, 0.0, 1.0)) + 0.5)
        pixels = bytearray(np.where(np.isnan(grid), UNKNOWN_PIXEL, shade).astype(np.uint8).tobytes())
    else:
        pixels = _pixels(dense)
    origin = f"{dense.x0_cells * dense.resolution_m:.10g} {dense.y0_cells * dense.resolution_m:.10g}"
    header = (
        f"P5\n# worldmodel {layer} layer; origin {origin} resolution {dense.resolution_m:.10g}\n"
        f"{dense.width} {dense.height}\n255\n"
    )
    with open(path, "wb") as out:
        out.write(header.encode("ascii"))
        out.write(pixels)


def _pixels(dense: worldmodel_shm.Dense) -> bytearray:
    pixels = bytearray(dense.width * dense.height)
    for image_row in range(dense.height):
        row = dense.height - 1 - image_row
        src = dense.values[row * dense.width : (row + 1) * dense.width]
        at = image_row * dense.width
        for col, p in enumerate(src):
            if math.isnan(p):
                pixels[at + col] = UNKNOWN_PIXEL
            else:  # floor(x + 0.5): halves round up as the server's std::lround does, not to even as round() does
                pixels[at + col] = int(math.floor(255.0 * (1.0 - min(max(float(p), 0.0), 1.0)) + 0.5))
    return pixels


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--server", default="http://127.0.0.1:8080", help="wmd's URL (default %(default)s)")
    source.add_argument("--name", help="the segment, wm-<uuid> or /dev/shm/wm-<uuid>, instead of asking the server")
    parser.add_argument("--layer", default="bayes", choices=worldmodel_shm.LAYERS)
    parser.add_argument("--pgm", metavar="FILE", help="write the layer as a PGM image")
    args = parser.parse_args()

    try:
        reader = worldmodel_shm.open_segment(args.name, args.server)
        with reader:
            dense = reader.read_layer(args.layer)
            tiles = reader.tile_count
            state = reader.state
            truncated = reader.tiles_truncated
    except (worldmodel_shm.ShmError, ValueError) as error:
        print(f"read_grid: {error}", file=sys.stderr)
        return 1

    cells = dense.width * dense.height
    known = worldmodel_shm.known_count(dense.values)
    if worldmodel_shm.HAVE_NUMPY:
        occupied = int((dense.values > OCCUPIED).sum())  # NaN compares false
    else:
        occupied = sum(1 for p in dense.values if p > OCCUPIED)
    print(f"segment:   {reader.name} ({state}{', tiles truncated' if truncated else ''})")
    print(f"layer:     {args.layer}")
    print(f"grid:      {dense.width} x {dense.height} cells at {dense.resolution_m} m, "
          f"origin ({dense.x0_cells * dense.resolution_m:.3f}, {dense.y0_cells * dense.resolution_m:.3f}) m")
    print(f"revision:  {dense.grid_revision}")
    print(f"tiles:     {tiles}")
    print(f"known:     {known} of {cells} cells ({known / cells if cells else 0.0:.1%})")
    label = "occupied (p > 0.65)" if args.layer == "bayes" else "above 0.65"
    print(f"{label}: {occupied} cells")
    if args.pgm:
        write_pgm(args.pgm, dense, args.layer)
        print(f"wrote {args.pgm}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
