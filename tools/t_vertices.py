#!/usr/bin/env python3
"""Counts T-vertices in a binary PLY written by `radiosity render --ply`: a vertex lying strictly
inside an edge of a triangle of the same plane (same unit normal, in the triangle's plane) without
being one of its corners. Independent of the project's code: reads the file as written.
usage: t_vertices.py MESH.ply   (prints the count; exits 1 when it is not zero)"""
import struct, sys
from collections import defaultdict

def read_ply(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    nv = nf = 0; props = []
    for line in header:
        w = line.split()
        if w[:2] == ["element", "vertex"]: nv = int(w[2]); cur = "v"
        elif w[:2] == ["element", "face"]: nf = int(w[2]); cur = "f"
        elif w[0] == "property" and cur == "v": props.append(w[1])
    size = {"float": 4, "uchar": 1}
    stride = sum(size[p] for p in props)
    verts = []
    for i in range(nv):
        x, y, z, nx, ny, nz = struct.unpack_from("<6f", data, end + i * stride)
        verts.append(((x, y, z), (nx, ny, nz)))
    at = end + nv * stride; tris = []
    for i in range(nf):
        n = data[at]; tris.append(struct.unpack_from("<%dI" % n, data, at + 1)); at += 1 + 4 * n
    return verts, tris

def main():
    verts, tris = read_ply(sys.argv[1])
    lengths = sorted(sum((verts[t[k]][0][c] - verts[t[(k + 1) % 3]][0][c]) ** 2 for c in range(3)) ** 0.5
                     for t in tris[:5000] for k in range(3))
    cell = max(lengths[len(lengths) // 2], 1e-9)
    grid = defaultdict(list)
    key = lambda p: tuple(int(p[c] // cell) for c in range(3))
    for i, (p, n) in enumerate(verts):
        grid[key(p)].append(i)
    count = 0
    for t in tris:
        for k in range(3):
            a, b = t[k], t[(k + 1) % 3]
            pa, pb = verts[a][0], verts[b][0]; na = verts[a][1]
            d = [pb[c] - pa[c] for c in range(3)]; l2 = sum(x * x for x in d)
            if l2 == 0: continue
            lo = key([min(pa[c], pb[c]) - 1e-6 for c in range(3)]); hi = key([max(pa[c], pb[c]) + 1e-6 for c in range(3)])
            for gx in range(lo[0], hi[0] + 1):
                for gy in range(lo[1], hi[1] + 1):
                    for gz in range(lo[2], hi[2] + 1):
                        for v in grid.get((gx, gy, gz), ()):
                            if v in t: continue
                            p, n = verts[v]
                            if sum((n[c] - na[c]) ** 2 for c in range(3)) > 1e-6: continue
                            s = sum((p[c] - pa[c]) * d[c] for c in range(3)) / l2
                            if s <= 1e-4 or s >= 1 - 1e-4: continue
                            off = sum((p[c] - pa[c] - s * d[c]) ** 2 for c in range(3))
                            if off <= (1e-5 * l2 ** 0.5) ** 2 + 1e-12: count += 1
    print(count)
    sys.exit(0 if count == 0 else 1)

main()
