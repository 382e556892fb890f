#!/usr/bin/env python3
"""Independent cross-check of reference_lights.py: plain Radiance ambient
calculation (rtrace -I -ab 64 -aa 0 -ad N -as 0 -lr 0, no irradiance cache,
Russian roulette) on the scene octree that reference_lights.py kept
(--keep DIR), with the sky (if any) as a glow that Radiance's ambient rays
find.  The direct part of lights at x is rtrace's -dj 0 one in both.

usage: ambient_check.py KEEPDIR SCENE.obj POINTS.txt OUT_of_reference_lights.txt [--ad N]
"""
import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import reference_lights as rl  # noqa: E402
ref = rl.ref
obj2rad = rl.obj2rad

ap = argparse.ArgumentParser()
ap.add_argument("keep"); ap.add_argument("scene"); ap.add_argument("points"); ap.add_argument("out")
ap.add_argument("--ad", type=int, default=4096)
ap.add_argument("--procs", type=int, default=2)
a = ap.parse_args()
ref.ENV = ref.radiance_env()
ref.ENV["RAYPATH"] = a.keep + os.pathsep + ref.ENV["RAYPATH"]
scene = obj2rad.parse_obj(a.scene)
polys = obj2rad.planar_polygons(scene)
diag = obj2rad.scene_diag(scene)
pts = ref.load_points(a.points)
idx, _ = ref.match_faces(pts, polys, diag)
xe = ref.eval_points(pts, idx, polys, ref.offset_length(polys, 1e-4))
n = pts[:, 3:]
# main scene + the sky glow (if sky.oct exists, its .rad has the sky text)
rad = open(os.path.join(a.keep, "scene.oct.rad")).read()
skyrad = os.path.join(a.keep, "sky.oct.rad")
if os.path.exists(skyrad):
    s = open(skyrad).read()
    rad += s[s.index("void brightfunc rl_skyf"):]
oct_ = ref.oconv(rad, os.path.join(a.keep, "ambient.oct"))
opts = ["-I", "-aa", "0", "-ad", str(a.ad), "-as", "0", "-ar", "0", "-dj", "0", "-ds", "0.05",
        "-dt", "0", "-dc", "1", "-dr", "0", "-lr", "0", "-lw", "%g" % (0.05 / a.ad), "-u+",
        "-ab", "64"]
e_amb = ref.rtrace(oct_, opts, ref.irays(xe, n), 3, a.procs)
got = np.loadtxt(a.out, comments="#", usecols=range(9))
e, se = got[:, :3], got[:, 6:9]
em, am, sm = e.mean(1), e_amb.mean(1), se.mean(1)
ok = (am > 0) & (sm > 0)
print("%d points with E = 0 in both: %d" % (len(em), int(np.sum((am == 0) & (em == 0)))))
em, am, sm = em[ok], am[ok], sm[ok]
e, e_amb = e[ok], e_amb[ok]
print("points %d: sum(paths)/sum(ambient) - 1 = %+.2e; per-point rms rel. diff %.2e; "
      "z (paths sE only) mean %+.2f rms %.2f"
      % (len(em), em.sum() / am.sum() - 1, np.sqrt(np.mean((em / am - 1) ** 2)),
         np.mean((em - am) / sm), np.sqrt(np.mean(((em - am) / sm) ** 2))))
print("per channel sum ratio - 1:", (e.sum(0) / e_amb.sum(0) - 1))
