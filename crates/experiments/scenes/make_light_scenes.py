#!/usr/bin/env python3
"""Writes the rooms `radiosity experiment validate` lights with lights that
are not surfaces: lamp_room.obj (a point light and a spot over a table, no
emitting surface) and window_room.obj (a room with a window and a skylight,
lit by --sun and --sky, no emitting surface), with their materials. Run from
this folder: python3 make_light_scenes.py"""

W, H, D = 5.0, 3.0, 4.0


def writer():
    lines, count = [], [0]

    def quad(o, u, v, mtl):
        pts = [o, [o[i] + u[i] for i in range(3)],
               [o[i] + u[i] + v[i] for i in range(3)], [o[i] + v[i] for i in range(3)]]
        lines.append("usemtl " + mtl)
        for p in pts:
            lines.append("v %g %g %g" % tuple(p))
        n = count[0]
        lines.append("f %d %d %d %d" % (n + 1, n + 2, n + 3, n + 4))
        count[0] += 4
    return lines, quad


def box(quad, x0, y0, z0, x1, y1, z1, mtl):
    """An outward-facing box."""
    dx, dy, dz = x1 - x0, y1 - y0, z1 - z0
    quad([x0, y1, z0], [0, 0, dz], [dx, 0, 0], mtl)  # top, +y
    quad([x0, y0, z0], [dx, 0, 0], [0, 0, dz], mtl)  # bottom, -y
    quad([x0, y0, z0], [0, 0, dz], [0, dy, 0], mtl)  # -x
    quad([x1, y0, z0], [0, dy, 0], [0, 0, dz], mtl)  # +x
    quad([x0, y0, z0], [0, dy, 0], [dx, 0, 0], mtl)  # -z
    quad([x0, y0, z1], [dx, 0, 0], [0, dy, 0], mtl)  # +z


MTL = """newmtl white
Kd 0.7 0.7 0.7
newmtl floor
Kd 0.45 0.35 0.25
newmtl red
Kd 0.6 0.15 0.1
newmtl green
Kd 0.15 0.5 0.2
newmtl table
Kd 0.5 0.5 0.55
"""


def lamp_room():
    lines, quad = writer()
    head = ["# A room lit by a point light and a spot, no emitting surface.",
            "#@light point 2.5 2.6 2.0 250",
            "#@light spot 1.2 2.9 1.0 0.2 -1 0.3 900 20 35 1 0.9 0.8",
            "#@camera 2.5 1.6 3.9 2.5 1.0 0 0 1 0 60", "mtllib lamp_room.mtl"]
    quad([0, 0, 0], [0, 0, D], [W, 0, 0], "floor")        # floor, +y
    quad([0, H, 0], [W, 0, 0], [0, 0, D], "white")        # ceiling, -y
    quad([0, 0, 0], [0, H, 0], [0, 0, D], "red")          # x = 0, +x
    quad([W, 0, 0], [0, 0, D], [0, H, 0], "green")        # x = W, -x
    quad([0, 0, 0], [W, 0, 0], [0, H, 0], "white")        # z = 0, +z
    quad([0, 0, D], [0, H, 0], [W, 0, 0], "white")        # z = D, -z
    box(quad, 1.8, 0.0, 1.4, 3.2, 0.75, 2.4, "table")
    return "\n".join(head + lines) + "\n"


def window_room():
    lines, quad = writer()
    head = ["# A room with a window in its south wall (z = D) and a skylight,",
            "# lit by daylight (--sun, --sky), no emitting surface.",
            "#@camera 2.5 1.6 0.2 2.5 1.0 4 0 1 0 70", "mtllib window_room.mtl"]
    quad([0, 0, 0], [0, 0, D], [W, 0, 0], "floor")
    # Ceiling (facing down) around a 1 x 1 m skylight over [1, 2] x [1, 2].
    def ceiling(x0, z0, x1, z1):
        quad([x0, H, z0], [x1 - x0, 0, 0], [0, 0, z1 - z0], "white")
    ceiling(0, 0, W, 1); ceiling(0, 2, W, D); ceiling(0, 1, 1, 2); ceiling(2, 1, W, 2)
    quad([0, 0, 0], [0, H, 0], [0, 0, D], "red")
    quad([W, 0, 0], [0, 0, D], [0, H, 0], "green")
    quad([0, 0, 0], [W, 0, 0], [0, H, 0], "white")
    # South wall (z = D, facing -z) around a 2 x 1.2 m window over
    # x in [1.5, 3.5], y in [0.9, 2.1].
    def south(x0, y0, x1, y1):
        quad([x0, y0, D], [0, y1 - y0, 0], [x1 - x0, 0, 0], "white")
    south(0, 0, W, 0.9); south(0, 2.1, W, H); south(0, 0.9, 1.5, 2.1); south(3.5, 0.9, W, 2.1)
    box(quad, 2.8, 0.0, 1.2, 4.0, 0.75, 2.2, "table")
    return "\n".join(head + lines) + "\n"


for name, text in [("lamp_room", lamp_room()), ("window_room", window_room())]:
    open(name + ".obj", "w").write(text)
    open(name + ".mtl", "w").write(MTL)
