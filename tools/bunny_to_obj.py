#!/usr/bin/env python3
"""Convert the Stanford bunny of the npm package `bunny` (public domain) to OBJ.

Usage:
    npm pack bunny && tar xzf bunny-*.tgz
    python3 tools/bunny_to_obj.py package/index.js > scenes/meshes/bunny.obj

The script checks that the mesh is closed (every undirected edge is shared by
exactly two triangles, each direction used once) and closes any boundary loop
it finds with a fan around the loop's centroid, so the result is watertight.
Package version 1.0.1 (1839 vertices, 3674 triangles) is already closed: the
script reports 0 boundary loops for it. sigmap's loader checks closure again.
Coordinates are kept as published (y up, about 10 units across); a scene
scales and rotates the mesh with its pose.
"""
import json
import re
import sys
from collections import Counter, defaultdict


def load(path):
    text = open(path).read()
    positions = json.loads(re.search(r"exports.positions=(\[.*?\]\])", text, re.S).group(1))
    cells = json.loads(re.search(r"exports.cells=(\[.*\]\])", text, re.S).group(1))
    return positions, cells


def boundary_loops(cells):
    directed = Counter()
    for a, b, c in cells:
        for u, v in ((a, b), (b, c), (c, a)):
            directed[(u, v)] += 1
    if any(n > 1 for n in directed.values()):
        sys.exit("inconsistent orientation or non-manifold edge: cannot close automatically")
    # A boundary edge u->v has no twin v->u; the hole is walked the other way.
    nxt = defaultdict(list)
    for (u, v) in directed:
        if (v, u) not in directed:
            nxt[v].append(u)
    loops, seen = [], set()
    for start in list(nxt):
        if start in seen:
            continue
        loop, cur = [], start
        while cur not in seen:
            seen.add(cur)
            loop.append(cur)
            cur = nxt[cur][0]
        loops.append(loop)
    return loops


def main():
    positions, cells = load(sys.argv[1])
    loops = boundary_loops(cells)
    for loop in loops:
        centre = [sum(positions[i][k] for i in loop) / len(loop) for k in range(3)]
        positions.append(centre)
        c = len(positions) - 1
        for i in range(len(loop)):
            cells.append([loop[i], loop[(i + 1) % len(loop)], c])
    print(f"closed {len(loops)} boundary loops", file=sys.stderr)
    print("# Stanford bunny (Stanford 3D Scanning Repository), public domain,")
    print("# from the npm package `bunny` 1.0.1; converted by tools/bunny_to_obj.py")
    print(f"# {len(positions)} vertices, {len(cells)} triangles, closed, outward (CCW) faces")
    for x, y, z in positions:
        print(f"v {x:.6f} {y:.6f} {z:.6f}")
    for a, b, c in cells:
        print(f"f {a + 1} {b + 1} {c + 1}")


if __name__ == "__main__":
    main()
