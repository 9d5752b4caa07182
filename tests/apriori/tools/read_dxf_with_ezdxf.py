#!/usr/bin/python3
"""Reads a DXF file with ezdxf (recover mode, which also audits it) and prints what it found as JSON:
{"version", "insunits", "audit_errors", "layers": {name: color}, "entities": [{"type", "layer", "closed",
"points": [[x, y], ...]}]}. Used by dxf_writer_test.cpp to check that other tools read write_dxf's output.
Exits with status 1 when ezdxf is missing, so that the test fails rather than skips."""
import json
import sys

try:
    import ezdxf
    from ezdxf import recover
except ImportError as e:
    print(f"read_dxf_with_ezdxf.py: python3-ezdxf is required ({e})", file=sys.stderr)
    sys.exit(1)


def main(path):
    doc, auditor = recover.readfile(path)
    entities = []
    for e in doc.modelspace():
        t = e.dxftype()
        if t == "LINE":
            points, closed = [e.dxf.start, e.dxf.end], False
        elif t == "POLYLINE":
            points, closed = [v.dxf.location for v in e.vertices], e.is_closed
        elif t == "LWPOLYLINE":
            points, closed = list(e.vertices_in_wcs()), e.closed
        else:
            points, closed = [], False
        entities.append({"type": t, "layer": e.dxf.layer, "closed": closed,
                         "points": [[p[0], p[1]] for p in points]})
    print(json.dumps({"version": doc.dxfversion, "insunits": doc.header.get("$INSUNITS", 0),
                      "audit_errors": len(auditor.errors),
                      "layers": {layer.dxf.name: layer.dxf.color for layer in doc.layers},
                      "entities": entities}))


if __name__ == "__main__":
    main(sys.argv[1])
