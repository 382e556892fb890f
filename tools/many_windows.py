#!/usr/bin/env python3
"""Writes many_windows.obj/.mtl: a 12 x 8 x 3 m room with 20 windows
(1.2 x 1.2 m, sill 0.9 m, every 2 m along each wall) and two 1 x 1 m
skylights, walls grey (Kd 0.5), floor 0.3, ceiling 0.7: the scene of the
sky's cost with many openings (`radiosity render many_windows.obj --sky
overcast --sky-illuminance 10000`).

usage: many_windows.py OUTDIR
"""
import os
import sys

W, D, H = 12.0, 8.0, 3.0
SILL, HEAD, WIN = 0.9, 2.1, 1.2


def cuts(length):
    """Window centres every 2 m, 1 m in from the corners."""
    centres = [1.0 + 2.0 * k for k in range(int(length // 2.0))]
    edges = [0.0]
    for c in centres:
        edges += [c - WIN / 2, c + WIN / 2]
    edges.append(length)
    return edges, centres


def main(out):
    os.makedirs(out, exist_ok=True)
    verts, faces = [], []

    def quad(p, mat):
        base = len(verts) + 1
        verts.extend(p)
        faces.append((mat, [base, base + 1, base + 2, base + 3]))

    def wall(origin, u, v, length):
        """A wall from origin along unit u (length) and up v (H), facing u x v,
        as a grid of quads with the window cells left out."""
        xs, centres = cuts(length)
        ys = [0.0, SILL, HEAD, H]
        for i in range(len(xs) - 1):
            for j in range(3):
                window = i % 2 == 1 and j == 1
                if window:
                    continue
                a, b, c, d = xs[i], xs[i + 1], ys[j], ys[j + 1]
                p = lambda s, t: [origin[k] + u[k] * s + v[k] * t for k in range(3)]
                quad([p(a, c), p(b, c), p(b, d), p(a, d)], "wall")

    up = (0.0, 1.0, 0.0)
    # Facing inward: u x v points into the room.
    wall((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), up, W)       # z = 0, faces +z
    wall((W, 0.0, D), (-1.0, 0.0, 0.0), up, W)          # z = D, faces -z
    wall((0.0, 0.0, D), (0.0, 0.0, -1.0), up, D)        # x = 0, faces +x
    wall((W, 0.0, 0.0), (0.0, 0.0, 1.0), up, D)         # x = W, faces -x
    quad([[0, 0, 0], [0, 0, D], [W, 0, D], [W, 0, 0]], "floor")
    # The ceiling (facing down) with two 1 x 1 skylights over x in [3, 4]
    # and [8, 9], z in [3.5, 4.5].
    xs = [0.0, 3.0, 4.0, 8.0, 9.0, W]
    zs = [0.0, 3.5, 4.5, D]
    for i in range(len(xs) - 1):
        for j in range(len(zs) - 1):
            if j == 1 and i in (1, 3):
                continue
            a, b, c, d = xs[i], xs[i + 1], zs[j], zs[j + 1]
            quad([[a, H, c], [b, H, c], [b, H, d], [a, H, d]], "ceiling")
    with open(os.path.join(out, "many_windows.obj"), "w") as fh:
        fh.write("# written by tools/many_windows.py\nmtllib many_windows.mtl\n")
        for v in verts:
            fh.write("v %g %g %g\n" % tuple(v))
        current = None
        for mat, f in faces:
            if mat != current:
                fh.write("usemtl %s\n" % mat)
                current = mat
            fh.write("f %s\n" % " ".join(map(str, f)))
    with open(os.path.join(out, "many_windows.mtl"), "w") as fh:
        fh.write("newmtl wall\nKd 0.5 0.5 0.5\nnewmtl floor\nKd 0.3 0.3 0.3\n"
                 "newmtl ceiling\nKd 0.7 0.7 0.7\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else ".")
