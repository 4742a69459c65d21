#!/usr/bin/env python3
"""A mapper of your own, in the protocol of sigmap's [[mapper]] tables.

sigmap exports each run's scans (believed poses only) and runs this program
without a shell, in a private folder, as the experiment's `command` says:

    python3 ray_mapper.py SCANS.graph OUT.ot RESOLUTION MAX_RANGE

It reads the OctoMap ScanGraph, maps it with OctoMap's ray update (each
scan: the cells its rays cross are free, the cells its points end in are
occupied, occupied winning; log-odds +0.847 / -0.405, clamped to
[-2, 3.5]) and writes an OctoMap .ot file (log-odds kept) that sigmap
reads and scores like its own maps. Plain Python 3, no packages: slow (seconds for the quickstart at
2 cm), but every step is visible. Replace the middle with your method.
"""

import math
import struct
import sys

HIT, MISS = 0.8472978603872037, -0.4054651081081643  # logodds(0.7), logodds(0.4)
CLAMP_MIN, CLAMP_MAX = -2.0, 3.5
KEY_OFFSET = 32768  # OctoMap's key of coordinate x: floor(x / resolution) + 32768


def read_scan_graph(path):
    """The nodes of a ScanGraph: (rotation rows, translation, points)."""
    data = open(path, "rb").read()
    at = 0

    def take(fmt):
        nonlocal at
        values = struct.unpack_from("<" + fmt, data, at)
        at += struct.calcsize("<" + fmt)
        return values

    def vector():
        (n,) = take("i")
        assert n == 3, "a vector3 has 3 values"
        return take("ddd")

    (count,) = take("I")
    nodes = []
    for _ in range(count):
        (n,) = take("I")
        points = [vector() for _ in range(n)]
        translation = vector()
        (four,) = take("i")
        assert four == 4, "a quaternion has 4 values"
        w, x, y, z = take("dddd")
        rotation = (
            (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
            (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
            (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
        )
        take("I")  # the node's id
        nodes.append((rotation, translation, points))
    return nodes


def key(p, resolution):
    return tuple(int(math.floor(c / resolution)) + KEY_OFFSET for c in p)


def ray_cells(origin, end, resolution):
    """The cells a segment crosses before its end cell (Amanatides & Woo)."""
    cell, last = list(key(origin, resolution)), key(end, resolution)
    direction = [e - o for o, e in zip(origin, end)]
    length = math.sqrt(sum(d * d for d in direction))
    if length == 0.0:
        return []
    step, t_max, t_delta = [0] * 3, [math.inf] * 3, [math.inf] * 3
    for i in range(3):
        d = direction[i] / length
        if d != 0.0:
            step[i] = 1 if d > 0 else -1
            border = (cell[i] - KEY_OFFSET + (step[i] > 0)) * resolution
            t_max[i] = (border - origin[i]) / d
            t_delta[i] = resolution / abs(d)
    cells = []
    while tuple(cell) != last:
        cells.append(tuple(cell))
        i = min(range(3), key=lambda a: t_max[a])
        if t_max[i] > length:
            break
        cell[i] += step[i]
        t_max[i] += t_delta[i]
    return cells


def map_scans(nodes, resolution, max_range):
    """Log-odds per finest cell, scan by scan as OctoMap inserts them."""
    log_odds = {}
    for rotation, origin, points in nodes:
        free, occupied = set(), set()
        for p in points:
            end = [sum(r * c for r, c in zip(row, p)) + t for row, t in zip(rotation, origin)]
            reach = math.sqrt(sum(c * c for c in p))
            if reach > max_range:  # no return: free space up to the maximum range
                end = [o + (e - o) * max_range / reach for o, e in zip(origin, end)]
                free.update(ray_cells(origin, end, resolution))
                free.add(key(end, resolution))
            else:
                free.update(ray_cells(origin, end, resolution))
                occupied.add(key(end, resolution))
        for cell in free - occupied:
            log_odds[cell] = max(CLAMP_MIN, log_odds.get(cell, 0.0) + MISS)
        for cell in occupied:
            log_odds[cell] = min(CLAMP_MAX, log_odds.get(cell, 0.0) + HIT)
    return log_odds


def write_ot(path, log_odds, resolution):
    """An OctoMap .ot file: pre-order, each node its f32 log-odds (an inner
    node the maximum of its children's) and a byte whose bit i says child i
    exists; unpruned."""
    root = {}
    for (kx, ky, kz), value in log_odds.items():
        node = root
        for depth in range(16):
            bit = 15 - depth
            child = ((kx >> bit) & 1) | (((ky >> bit) & 1) << 1) | (((kz >> bit) & 1) << 2)
            if depth == 15:
                node[child] = value
            else:
                node = node.setdefault(child, {})

    def value(node):
        return node if not isinstance(node, dict) else max(value(c) for c in node.values())

    out = bytearray()
    count = [0]

    def write(node):
        count[0] += 1
        out.extend(struct.pack("<f", value(node)))
        if not isinstance(node, dict):
            out.append(0)
            return
        out.append(sum(1 << i for i in node))
        for i in sorted(node):
            write(node[i])

    if root:
        write(root)
    header = (
        "# Octomap OcTree file\n# written by sigmap's example mapper\n"
        f"id OcTree\nsize {count[0]}\nres {resolution!r}\ndata\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode() + bytes(out))


def main(argv):
    if len(argv) != 5:
        sys.exit("usage: ray_mapper.py SCANS.graph OUT.ot RESOLUTION MAX_RANGE")
    graph, out, resolution, max_range = argv[1], argv[2], float(argv[3]), float(argv[4])
    nodes = read_scan_graph(graph)
    write_ot(out, map_scans(nodes, resolution, max_range), resolution)
    print(f"{len(nodes)} scans mapped at {resolution} m into {out}")


if __name__ == "__main__":
    main(sys.argv)
