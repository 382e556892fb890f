#!/usr/bin/env python3
"""Writes cathedral.obj/.mtl: a many-emitter stress scene for the final
pass. A 40 x 14 x 18 m nave whose two long walls carry tall windows of
stained glass, each window a grid of small emitting panes (separated by
leading, so no two panes merge into one surface), a rose window of panes
at the west end, two rows of pillars, pews in rows, an altar and 900
chairs in the aisles: 1,000+ emitting faces over a cluttered interior
(34,000 faces), lit by nothing else.

    python3 tools/cathedral.py OUTDIR [--windows N] [--columns C] [--rows R]
    radiosity render OUTDIR/cathedral.obj --stats S.json

The defaults give 10 windows a side of 4 x 13 panes and a rose of 87
panes: 1,127 emitting faces.
"""
import argparse
import math
import os

L, W, H = 40.0, 14.0, 18.0
GLASS = [  # stained glass exitances (W/m^2 per channel)
    (30.0, 6.0, 4.0),
    (5.0, 10.0, 32.0),
    (8.0, 26.0, 8.0),
    (30.0, 24.0, 6.0),
    (22.0, 22.0, 26.0),
    (18.0, 6.0, 24.0),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--windows", type=int, default=10, help="windows a side")
    ap.add_argument("--columns", type=int, default=4, help="panes across a window")
    ap.add_argument("--rows", type=int, default=13, help="panes up a window")
    ap.add_argument(
        "--chairs", type=int, default=900, help="chairs in the aisles (the clutter)"
    )
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    verts, faces = [], []

    def quad(corners, material):
        base = len(verts) + 1
        verts.extend(corners)
        faces.append((material, [base, base + 1, base + 2, base + 3]))

    def rect(origin, u, v, material):
        """The quad origin, +u, +u+v, +v: its front is u x v."""
        o = origin
        quad(
            [
                o,
                [o[k] + u[k] for k in range(3)],
                [o[k] + u[k] + v[k] for k in range(3)],
                [o[k] + v[k] for k in range(3)],
            ],
            material,
        )

    def box(lo, hi, material):
        """An axis-aligned box, faces outward."""
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
        rect([x0, y0, z0], [0, dy, 0], [dx, 0, 0], material)  # z0 face, -z
        rect([x0, y0, z1], [dx, 0, 0], [0, dy, 0], material)  # z1 face, +z
        rect([x0, y0, z0], [0, 0, dz], [0, dy, 0], material)  # x0 face, -x
        rect([x1, y0, z0], [0, dy, 0], [0, 0, dz], material)  # x1 face, +x
        rect([x0, y0, z0], [dx, 0, 0], [0, 0, dz], material)  # y0 face, -y
        rect([x0, y1, z0], [0, 0, dz], [dx, 0, 0], material)  # y1 face, +y

    # The shell, facing inward.
    rect([0, 0, 0], [0, 0, W], [L, 0, 0], "floor")
    rect([0, H, 0], [L, 0, 0], [0, 0, W], "vault")
    rect([0, 0, 0], [L, 0, 0], [0, H, 0], "stone")  # z = 0, faces +z
    rect([L, 0, W], [-L, 0, 0], [0, H, 0], "stone")  # z = W, faces -z
    rect([0, 0, W], [0, 0, -W], [0, H, 0], "stone")  # x = 0, faces +x
    rect([L, 0, 0], [0, 0, W], [0, H, 0], "stone")  # x = L, faces -x

    panes = 0
    inset = 0.02  # panes stand off the wall by this much
    lead = 0.04  # leading between panes
    width, bottom, top = 1.8, 5.0, 14.0
    pitch = L / args.windows
    pane_w = width / args.columns
    pane_h = (top - bottom) / args.rows
    for side in (0, 1):
        for k in range(args.windows):
            x0 = pitch * (k + 0.5) - width / 2
            for i in range(args.columns):
                for j in range(args.rows):
                    glass = f"glass{(i + j + k) % len(GLASS)}"
                    a = x0 + i * pane_w + lead / 2
                    b = a + pane_w - lead
                    y = bottom + j * pane_h + lead / 2
                    h = pane_h - lead
                    if side == 0:
                        rect([a, y, inset], [b - a, 0, 0], [0, h, 0], glass)
                    else:
                        rect([b, y, W - inset], [a - b, 0, 0], [0, h, 0], glass)
                    panes += 1
    # The rose window on the west wall (x = 0), panes within a circle.
    centre, radius, cell = (W / 2, 13.0), 3.2, 0.6
    n = int(2 * radius / cell)
    for i in range(n):
        for j in range(n):
            z = centre[0] - radius + (i + 0.5) * cell
            y = centre[1] - radius + (j + 0.5) * cell
            if math.hypot(z - centre[0], y - centre[1]) > radius:
                continue
            glass = f"glass{(i * 3 + j) % len(GLASS)}"
            s = cell - lead
            rect([inset, y - s / 2, z + s / 2], [0, 0, -s], [0, s, 0], glass)
            panes += 1

    # Two rows of pillars, pews between them, an altar at the east end.
    for k in range(1, 10):
        x = 4.0 * k
        for z in (3.5, W - 3.5):
            box([x - 0.5, 0, z - 0.5], [x + 0.5, H, z + 0.5], "stone")
    for row in range(16):
        x = 4.0 + 1.4 * row
        for z0, z1 in ((4.4, 6.6), (7.4, 9.6)):
            box([x, 0.0, z0], [x + 0.5, 0.45, z1], "wood")
            box([x + 0.45, 0.45, z0], [x + 0.55, 1.0, z1], "wood")
    box([35.0, 0.0, 5.0], [36.5, 1.1, 9.0], "altar")
    # Chairs in rows along both aisles: a seat, a back and four legs each.
    spots = [
        (2.0 + 0.7 * i, z)
        for i in range(46)
        for z in (0.6, 1.3, 2.0, W - 2.6, W - 1.9, W - 1.2)
    ]
    for x, z in spots[: args.chairs]:
        box([x, 0.42, z], [x + 0.45, 0.47, z + 0.45], "wood")
        box([x + 0.4, 0.47, z], [x + 0.45, 0.9, z + 0.45], "wood")
        for dx, dz in ((0, 0), (0.4, 0), (0, 0.4), (0.4, 0.4)):
            box([x + dx, 0, z + dz], [x + dx + 0.05, 0.42, z + dz + 0.05], "wood")

    with open(os.path.join(args.out, "cathedral.obj"), "w") as fh:
        fh.write("# written by tools/cathedral.py\nmtllib cathedral.mtl\n")
        fh.write(f"# {panes} emitting panes\n")
        for v in verts:
            fh.write("v {:.4f} {:.4f} {:.4f}\n".format(*v))
        current = None
        for material, idx in faces:
            if material != current:
                fh.write(f"usemtl {material}\n")
                current = material
            fh.write("f " + " ".join(str(i) for i in idx) + "\n")
    with open(os.path.join(args.out, "cathedral.mtl"), "w") as fh:
        for name, kd in (
            ("floor", 0.35),
            ("vault", 0.6),
            ("stone", 0.5),
            ("wood", 0.25),
            ("altar", 0.7),
        ):
            fh.write(f"newmtl {name}\nKd {kd} {kd} {kd}\n\n")
        for k, ke in enumerate(GLASS):
            fh.write(f"newmtl glass{k}\nKd 0.1 0.1 0.1\nKe {ke[0]} {ke[1]} {ke[2]}\n\n")
    print(f"{panes} emitting panes, {len(faces)} faces")


if __name__ == "__main__":
    main()
