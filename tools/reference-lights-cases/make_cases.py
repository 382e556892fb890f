#!/usr/bin/env python3
"""Writes the test scenes and points for tools/reference_lights.py (see
../README-reference-lights.md).  Run from anywhere; files go beside this script."""
import os

HERE = os.path.dirname(os.path.abspath(__file__))
FLOOR = """v -2 0 -2
v -2 0 2
v 2 0 2
v 2 0 -2
usemtl floor
f 1 2 3 4
"""


def write(name, text, mtl, points):
    with open(os.path.join(HERE, name + ".obj"), "w") as fh:
        fh.write("mtllib %s.mtl\n" % name + text)
    with open(os.path.join(HERE, name + ".mtl"), "w") as fh:
        fh.write(mtl)
    with open(os.path.join(HERE, name + ".pts"), "w") as fh:
        for p in points:
            fh.write("%.6f %.6f %.6f %g %g %g\n" % tuple(p))


def floor_pts(xz):
    return [(x, 0, z, 0, 1, 0) for x, z in xz]


MTL_FLOOR = "newmtl floor\nKd 0.5 0.5 0.5\n"

# 1. point light over the floor
write("floor_point", "#@light point 0.3 2 -0.2 150\n" + FLOOR, MTL_FLOOR,
      floor_pts([(0.3, -0.2), (0, 0), (1, 0.5), (-1.5, 1.2), (1.9, -1.9), (-0.7, -1.1)]))

# 2. spot straight down from 2 m: inner 20 deg (r < 0.728), outer 35 (r > 1.400)
write("floor_spot", "#@light spot 0 2 0 0 -1 0 200 20 35 1 0.8 0.6\n" + FLOOR, MTL_FLOOR,
      floor_pts([(0, 0), (0.5, 0), (0, -0.7), (0.6, 0.6), (0.9, 0), (0, 1.1),
                 (-0.9, -0.9), (1.3, 0.1), (1.5, 0), (-1.2, 1.2), (1.9, 0.3)]))

# 3. sun along (0.37,-1,0.13), 60000 lux, and a black 0.4 x 0.4 blocker 1 m up
#    (its shadow: the square centred on (0.37, 0, 0.13))
BLOCK = """v -0.2 1 -0.2
v -0.2 1 0.2
v 0.2 1 0.2
v 0.2 1 -0.2
usemtl black
f 1 2 3 4
"""
write("floor_sun", "#@light sun 0.37 -1 0.13 60000\n" + FLOOR.replace("usemtl floor", "usemtl floor") +
      BLOCK.replace("v ", "v ").replace("f 1 2 3 4", "f 5 6 7 8"),
      MTL_FLOOR + "newmtl black\nKd 0 0 0\n",
      floor_pts([(0, 0), (1, 1), (-1.5, 0.5), (0.8, -1.5),          # lit
                 (0.37, 0.13), (0.30, 0.05), (0.45, 0.25),           # shadow
                 (0.37 + 0.19, 0.13), (0.37 + 0.21, 0.13)]))         # 1 cm either side of the edge

# 4a. open floor under a sky
write("floor_open", FLOOR, MTL_FLOOR, floor_pts([(0, 0), (1.2, -0.8), (-1.9, 1.9)]))

# 4d. a 200 x 200 m floor under the sky, points 1 m above it, off any face
#     (B = nan): everything the floor sends there comes through the paths'
#     deeper vertices (floor hit, then escape to the sky)
write("big_floor", "v -100 0 -100\nv -100 0 100\nv 100 0 100\nv 100 0 -100\nusemtl floor\nf 1 2 3 4\n",
      MTL_FLOOR, [(0, 1, 0, 1, 0, 0), (0, 1, 0, 0, -1, 0), (0, 1, 0, 0.5, -0.5, 0.7),
                  (3, 1, 2, -0.3, 0.2, 0.9)])

# 4b. closed 4x3x4 room, black, 1x1 skylight hole in the ceiling (y = 3)
V = []


def quad(a, b, c, d):
    V.extend([a, b, c, d])
    n = len(V)
    return "f %d %d %d %d\n" % (n - 3, n - 2, n - 1, n)


faces = "usemtl black\n"
faces += quad((-2, 0, -2), (-2, 0, 2), (2, 0, 2), (2, 0, -2))          # floor, up
faces += quad((-2, 0, -2), (2, 0, -2), (2, 3, -2), (-2, 3, -2))        # z=-2, normal +z
faces += quad((-2, 0, 2), (-2, 3, 2), (2, 3, 2), (2, 0, 2))            # z=+2, normal -z
faces += quad((-2, 0, -2), (-2, 3, -2), (-2, 3, 2), (-2, 0, 2))        # x=-2, normal +x
faces += quad((2, 0, -2), (2, 0, 2), (2, 3, 2), (2, 3, -2))            # x=+2, normal -x
# ceiling (normal -y) around the hole |x|,|z| < 0.5
for x0, x1, z0, z1 in [(-2, 2, -2, -0.5), (-2, 2, 0.5, 2), (-2, -0.5, -0.5, 0.5), (0.5, 2, -0.5, 0.5)]:
    faces += quad((x0, 3, z0), (x1, 3, z0), (x1, 3, z1), (x0, 3, z1))
obj = "".join("v %g %g %g\n" % v for v in V) + faces
write("skylight_room", obj, "newmtl black\nKd 0 0 0\n",
      floor_pts([(0, 0), (0.8, 0.3), (-1.5, -1.0)]))

# 4c. the same room with reflecting surfaces (floor 0.5, walls 0.6 0.5 0.4,
#     ceiling 0.7) for the cross-check with Radiance's own ambient calculation
#     (ambient_check.py); 40 points on floor, walls and ceiling
mats = ["floor"] + ["wall"] * 4 + ["ceiling"] * 4
lines = obj.split("usemtl black\n")[0]
for k, f in enumerate(l for l in faces.splitlines() if l.startswith("f ")):
    lines += "usemtl %s\n%s\n" % (mats[k], f)
pts = []
for i in range(10):
    u, v = (i * 0.37) % 1, (i * 0.61 + 0.2) % 1
    x, z = -1.9 + 3.8 * u, -1.9 + 3.8 * v
    pts.append((x, 0, z, 0, 1, 0))
    pts.append((x, 0.1 + 2.8 * v, -2, 0, 0, 1))
    pts.append((2, 0.1 + 2.8 * u, z, -1, 0, 0))
    if abs(x) > 0.55 or abs(z) > 0.55:
        pts.append((x, 3, z, 0, -1, 0))
write("skylight_room_white", lines,
      "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl wall\nKd 0.6 0.5 0.4\nnewmtl ceiling\nKd 0.7 0.7 0.7\n", pts)

# 5. the Cornell box with its ceiling lamp switched off (Ke 0, still Kd 0.78)
#    and a coloured point light 10 cm below the lamp instead; 300 random
#    points on the faces (area-weighted, seeded)
import random  # noqa: E402

SRC = "/work/shared/scenes/cornell_box/cornell_box"
obj_lines = open(SRC + ".obj").read().splitlines()
mtl = open(SRC + ".mtl").read().replace("Ke 65.3159 34.0754 8.7030", "Ke 0 0 0")
out = ["#@light point 0.278 0.4483 0.2795 40 1 0.7 0.35"]
verts, faces = [], []
for line in obj_lines:
    out.append(line.replace("mtllib cornell_box.mtl", "mtllib cornell_point.mtl"))
    t = line.split()
    if t and t[0] == "v":
        verts.append(tuple(float(s) for s in t[1:4]))
    elif t and t[0] == "f":
        faces.append([verts[int(s.split("/")[0]) - 1] for s in t[1:]])
with open(os.path.join(HERE, "cornell_point.obj"), "w") as fh:
    fh.write("\n".join(out) + "\n")
with open(os.path.join(HERE, "cornell_point.mtl"), "w") as fh:
    fh.write(mtl)


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


tris = []
for f in faces:
    for k in range(1, len(f) - 1):
        c = cross(sub(f[k], f[0]), sub(f[k + 1], f[0]))
        area = 0.5 * sum(x * x for x in c) ** 0.5
        if area > 0:
            tris.append((area, f[0], f[k], f[k + 1], [x / (2 * area) for x in c]))
rng = random.Random(5)
tot = sum(t[0] for t in tris)
pts = []
for _ in range(300):
    r = rng.random() * tot
    for area, a, b, c, nrm in tris:
        r -= area
        if r <= 0:
            break
    u, v = rng.random(), rng.random()
    if u + v > 1:
        u, v = 1 - u, 1 - v
    p = [a[i] + u * (b[i] - a[i]) + v * (c[i] - a[i]) for i in range(3)]
    pts.append(tuple(p) + tuple(nrm))
with open(os.path.join(HERE, "cornell_point.pts"), "w") as fh:
    for p in pts:
        fh.write("%.6f %.6f %.6f %.6f %.6f %.6f\n" % p)
