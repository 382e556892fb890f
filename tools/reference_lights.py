#!/usr/bin/env python3
"""Reference irradiance / radiosity with point, spot and sun lights and CIE
skies, computed with Radiance through the shared harness
(/work/shared/reference, imported unchanged: its OBJ parser, scene variants,
point handling and path-traced estimator design).

usage: reference_lights.py SCENE.obj POINTS.txt OUT.txt
           [--accuracy low|medium|high]
           [--sky uniform|overcast|clear --sky-illuminance LUX]
           [--sun ALTITUDE AZIMUTH LUX]
           [--paths N] [--sky-rays N] [--vertex-sky-rays K] [--procs N]
           [--seed S] [--keep DIR] [--point-radius R] [--sun-diameter DEG]
           [--harness DIR]

POINTS.txt and OUT.txt are exactly reference.py's (see its README):
  OUT.txt: '#' header lines, then per point
           Er Eg Eb  Br Bg Bb  sEr sEg sEb  material
  E = irradiance [W/m^2] with all interreflections, B = Ke + Kd E.

Lights (photometric, 179 lm/W per channel, colour = linear RGB multiplier):
  #@light point X Y Z CANDELA [R G B]
  #@light spot X Y Z DX DY DZ CANDELA INNER_DEG OUTER_DEG [R G B]
        intensity CANDELA*colour/179 * s^2, s = clamp((c-co)/(ci-co), 0, 1),
        c = cos of the angle to the axis, ci/co = cos(INNER)/cos(OUTER)
  #@light sun DX DY DZ LUX [R G B]       (DX DY DZ = where the light goes)
  --sun ALT AZ LUX: a white sun towards (sin az cos alt, sin alt, -cos az cos alt)
  --sky uniform|overcast|clear --sky-illuminance E_h (lux, unobstructed
        horizontal illuminance of the sky alone)
  --ground-reflectance RHO (0.2): below the horizon, with a sky, a ground of
        luminance RHO (E_h + E_sun sin(altitude)) / pi (gensky's ground)

Radiance models:
  point : sphere of radius r (--point-radius, 1 mm) with `light` radiance
          I/(pi r^2) (a Lambertian sphere has intensity L pi r^2 exactly);
  spot  : the same sphere, its `light` modified by a `brightfunc` of the
          emission direction -D (rl_spot.cal);
  sun   : distant `source` of --sun-diameter (0.01 deg: parallel, as the
          renderer's sun; 0.53 is the real sun's) with `light` radiance
          E_n / (2 pi (1 - cos(diam/2)));
  sky   : `glow` on a 180-degree `source` about +y with a `brightfunc`
          (rl_sky.cal) in our axes (y up, north -z, east +x); the ground a
          uniform `glow` on a 180-degree `source` about -y.
  Point, spot and sun lights are Radiance light sources: sampled directly
  (next-event estimation) at every path vertex and invisible to path rays
  (-dv-).  Radiance never samples a distant `glow` directly (it is skipped
  as a source, as for gensky skies): the sky is found by the path rays.

Estimator (reference.py's `paths`, extended):
  E(x) = Edir_emitters(x) + Edir_lights(x) + Esky_direct(x) + pi mean_i L_i
  Edir_emitters : reference.py's subdivided-source direct term (or its
                  hemisphere fallback near an emitter);
  Edir_lights   : rtrace -I -ab 0 -dj 0 on the lights alone (deterministic);
  Esky_direct   : sky seen directly from x, pi x mean radiance over
                  --sky-rays stratified cosine rays in a copy of the scene
                  whose surfaces are black (default 16 x paths, >= 4096);
  L_i           : reference.py's paths (cosine sampling, Radiance's jittered
                  next-event estimate at every vertex, Russian roulette);
                  at every vertex beyond x, the sky seen directly from there
                  is added from --vertex-sky-rays (4) stratified cosine rays
                  into the same black-surface copy (unbiased, like the
                  continuation ray's escape it replaces, with less noise).
"""
import argparse
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

HARNESS = os.environ.get("REFERENCE_HARNESS", "/work/shared/reference")
for _i, _arg in enumerate(sys.argv):
    if _arg == "--harness" and _i + 1 < len(sys.argv):
        HARNESS = sys.argv[_i + 1]
    elif _arg.startswith("--harness="):
        HARNESS = _arg.split("=", 1)[1]
sys.path.insert(0, HARNESS)
import obj2rad  # noqa: E402
import reference as ref  # noqa: E402

EFFICACY = 179.0

# ------------------------------------------------------------ .cal files
SPOT_CAL = """{ rl_spot.cal: spot falloff for reference_lights.py.
  A1 A2 A3: unit axis (direction the light goes); A4 = cos(inner);
  A5 = cos(outer).  For a source the ray direction D points from the shaded
  point to the source, so the emission direction is -D. }
spot_c = -(Dx*A1 + Dy*A2 + Dz*A3);
spot_s = if(A4 - A5 - 1e-12, (spot_c - A5)/(A4 - A5), 1);
spotf = if(spot_c - A4, 1, if(A5 - spot_c, 0, spot_s*spot_s));
"""

SKY_CAL = """{ rl_sky.cal: sky luminance distributions for reference_lights.py,
  in the project's axes: y up, north -z, east +x.  D = direction from the
  point towards the sky; nothing below the horizon (Dy <= 0).
  The glow's colour carries the absolute scale. }
sky_uniform = if(Dy, 1, 0);
{ CIE standard overcast: L = Lz (1 + 2 cos(theta))/3 }
sky_overcast = if(Dy, (1 + 2*Dy)/3, 0);
{ CIE clear sky (gensky +s form), A1 A2 A3 = unit vector towards the sun }
sky_dot = Dx*A1 + Dy*A2 + Dz*A3;
sky_cg = if(sky_dot - 1, 1, if(-1 - sky_dot, -1, sky_dot));
sky_gamma = acos(sky_cg);
{ exp(-0.32/Dy) < 1.3e-14 for Dy < 0.01: dropped there (no underflow) }
sky_clear = if(Dy, (0.91 + 10*exp(-3*sky_gamma) + 0.45*sky_cg*sky_cg)
                    * if(Dy - 0.01, 1 - exp(-0.32/Dy), 1), 0);
"""


def sky_shape(kind, d, sun=None):
    """Python twin of rl_sky.cal (relative luminance), d (n,3) unit."""
    dy = d[:, 1]
    up = dy > 0
    if kind == "uniform":
        return np.where(up, 1.0, 0.0)
    if kind == "overcast":
        return np.where(up, (1 + 2 * dy) / 3, 0.0)
    cg = np.clip(d @ np.asarray(sun), -1, 1)
    g = np.arccos(cg)
    with np.errstate(divide="ignore", over="ignore"):
        z = np.where(up, 1 - np.exp(-0.32 / np.where(up, dy, 1.0)), 0.0)
    return np.where(up, (0.91 + 10 * np.exp(-3 * g) + 0.45 * cg * cg) * z, 0.0)


def sky_horizontal_integral(kind, sun=None, nt=2048, nphi=4096):
    """K = integral over the upper hemisphere of shape * cos(theta) dw,
    midpoint rule in (cos^2 theta, phi) (cos theta sin theta dtheta =
    d(cos^2 theta)/2 ... uniform in u = cos^2)."""
    if kind == "uniform":
        return math.pi
    if kind == "overcast":
        return 7 * math.pi / 9
    # E = int_0^{2pi} int_0^1 shape * (1/2) du dphi with u = cos^2(theta)
    total = 0.0
    phis = (np.arange(nphi) + 0.5) / nphi * 2 * math.pi
    us = (np.arange(nt) + 0.5) / nt
    for k0 in range(0, nt, 256):
        u = us[k0:k0 + 256]
        ct = np.sqrt(u)
        st = np.sqrt(1 - u)
        d = np.stack([np.outer(st, np.sin(phis)), np.outer(ct, np.ones(nphi)),
                      -np.outer(st, np.cos(phis))], axis=-1).reshape(-1, 3)
        total += sky_shape(kind, d, sun).sum()
    return total * 0.5 * (1.0 / nt) * (2 * math.pi / nphi)


# ------------------------------------------------------------ lights
def parse_light_directives(path):
    lights = []
    with open(path) as fh:
        for no, line in enumerate(fh, 1):
            s = line.strip()
            if not s.startswith("#@light"):
                continue
            tok = s[len("#@light"):].split()
            if not tok:
                raise SystemExit("%s:%d: #@light without a type" % (path, no))
            kind = tok[0]
            need = {"point": 4, "spot": 9, "sun": 4}.get(kind)
            if need is None:
                raise SystemExit("%s:%d: light type %r is not supported here (point, spot, "
                                 "sun)" % (path, no, kind))
            try:
                nums = [float(t) for t in tok[1:]]
            except ValueError:
                raise SystemExit("%s:%d: not a number in %r" % (path, no, s))
            if len(nums) not in (need, need + 3):
                raise SystemExit("%s:%d: %d numbers after %r" % (path, no, len(nums), kind))
            if not all(math.isfinite(v) for v in nums):
                raise SystemExit("%s:%d: a number is not finite" % (path, no))
            col = np.array(nums[need:need + 3]) if len(nums) == need + 3 else np.ones(3)
            if np.any(col < 0) or nums[need - 1 if kind != "spot" else 6] < 0:
                raise SystemExit("%s:%d: negative intensity or colour" % (path, no))
            L = dict(kind=kind, colour=col, line=no)
            if kind == "point":
                L.update(pos=np.array(nums[:3]), cd=nums[3])
            elif kind == "spot":
                ax = np.array(nums[3:6])
                L.update(pos=np.array(nums[:3]), axis=ax / np.linalg.norm(ax), cd=nums[6],
                         inner=nums[7], outer=nums[8])
                if not (0 <= nums[7] <= nums[8] <= 90 and nums[8] > 0):
                    raise SystemExit("%s:%d: bad spot cone" % (path, no))
            else:
                d = np.array(nums[:3])
                L.update(dir=d / np.linalg.norm(d), lux=nums[3])
            lights.append(L)
    return lights


def sun_from_angles(alt, az, lux):
    a, z = math.radians(alt), math.radians(az)
    to_sun = np.array([math.sin(z) * math.cos(a), math.sin(a), -math.cos(z) * math.cos(a)])
    return dict(kind="sun", dir=-to_sun, lux=lux, colour=np.ones(3), line="--sun")


def lights_text(lights, mode, radius, sun_diam):
    """mode 'source': Radiance light sources; 'black': the light spheres as
    black opaque spheres (albedo / sky-only scenes; suns omitted)."""
    out = []
    for i, L in enumerate(lights):
        nm = "rl_light%d" % i
        if L["kind"] in ("point", "spot"):
            p = L["pos"]
            if mode == "black":
                out.append("void plastic %s_m\n0\n0\n5 0 0 0 0 0" % nm)
            else:
                le = L["colour"] * L["cd"] / EFFICACY / (math.pi * radius ** 2)
                if L["kind"] == "spot":
                    a = L["axis"]
                    ci, co = math.cos(math.radians(L["inner"])), math.cos(math.radians(L["outer"]))
                    out.append("void brightfunc %s_f\n2 spotf rl_spot.cal\n0\n5 %.12g %.12g %.12g %.12g %.12g"
                               % (nm, a[0], a[1], a[2], ci, co))
                    out.append("%s_f light %s_m\n0\n0\n3 %s" % (nm, nm, obj2rad.fmt3(le)))
                else:
                    out.append("void light %s_m\n0\n0\n3 %s" % (nm, obj2rad.fmt3(le)))
            out.append("%s_m sphere %s\n0\n0\n4 %s %.12g" % (nm, nm, obj2rad.fmt3(p), radius))
        elif L["kind"] == "sun" and mode == "source":
            omega = 2 * math.pi * (1 - math.cos(math.radians(sun_diam / 2)))
            le = L["colour"] * L["lux"] / EFFICACY / omega
            out.append("void light %s_m\n0\n0\n3 %s" % (nm, obj2rad.fmt3(le)))
            out.append("%s_m source %s\n0\n0\n4 %s %.12g"
                       % (nm, nm, obj2rad.fmt3(-L["dir"]), sun_diam))
    return "\n".join(out) + "\n"


def sky_text(sky):
    if sky is None:
        return ""
    fn = {"uniform": "sky_uniform", "overcast": "sky_overcast", "clear": "sky_clear"}[sky["kind"]]
    args = "3 %s" % obj2rad.fmt3(sky["sun"]) if sky["kind"] == "clear" else "0"
    text = ("void brightfunc rl_skyf\n2 %s rl_sky.cal\n0\n%s\n"
            "rl_skyf glow rl_skyg\n0\n0\n4 %s 0\n"
            "rl_skyg source rl_sky\n0\n0\n4 0 1 0 180\n" % (fn, args, obj2rad.fmt3(sky["L"])))
    if sky.get("ground") is not None and np.any(sky["ground"] > 0):
        text += ("void glow rl_groundg\n0\n0\n4 %s 0\n"
                 "rl_groundg source rl_ground\n0\n0\n4 0 -1 0 180\n"
                 % obj2rad.fmt3(sky["ground"]))
    return text


def black_materials(scene):
    return "\n".join("void plastic m_%s\n0\n0\n5 0 0 0 0 0" % obj2rad.radname(n)
                     for n in scene.materials) + "\n"


def plain_materials(scene):
    """Every surface an opaque reflector (no emission): occluders for the
    lights' own direct term."""
    return ref.mat_text(scene, "albedo", "light")


# ------------------------------------------------------------ estimator
def stratified_cosine(xe, n, m, rng):
    npts, k = len(xe), m * m
    ii, jj = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    u1 = (np.tile(ii.ravel(), npts) + rng.random(npts * k)) / m
    u2 = (np.tile(jj.ravel(), npts) + rng.random(npts * k)) / m
    org = np.repeat(xe, k, axis=0)
    dirs = ref.cosine_dirs(np.repeat(n, k, axis=0), u1, u2)
    return org, dirs


def sky_direct(oct_sky, xe, n, nrays, procs, rng, log):
    """pi x mean sky radiance over stratified cosine rays (surfaces black)."""
    m = max(1, int(round(math.sqrt(nrays))))
    k = m * m
    per = max(1, 2_000_000 // k)
    e = np.zeros((len(xe), 3))
    se = np.zeros((len(xe), 3))
    t = time.time()
    for c0 in range(0, len(xe), per):
        sl = slice(c0, c0 + per)
        org, dirs = stratified_cosine(xe[sl], n[sl], m, rng)
        v = math.pi * ref.rtrace(oct_sky, ["-ab", "0", "-av", "0", "0", "0", "-ov"],
                                 np.hstack([org, dirs]), 3, procs).reshape(-1, k, 3)
        e[sl] = v.mean(axis=1)
        se[sl] = v.std(axis=1, ddof=1) / math.sqrt(k)
    log("  sky seen directly: %d stratified cosine rays/point (%.1fs)" % (k, time.time() - t))
    return e, se


def paths_lights(oct_light, oct_albedo, oct_emit, oct_sky, xe, n, near, npaths, procs,
                 seed, diag, log, rr=0.05, max_depth=1000, sky_k=4):
    """reference.paths_method's path loop (indirect part + emitter hemisphere
    term), plus the sky seen directly from every path vertex beyond x:
    sky_k stratified cosine rays per vertex (sky_k = 0: the continuation
    ray's escape only)."""
    rng = np.random.default_rng(seed)
    npts = len(xe)
    m = int(round(math.sqrt(npaths)))
    npaths = m * m
    org, dirs = stratified_cosine(xe, n, m, rng)
    thr = np.ones((len(org), 3))
    acc = np.zeros((len(org), 3))
    eps = max(2e-6, 1e-9 * diag)
    opts_alb = ["-ab", "0", "-av", "1", "1", "1", "-aw", "0", "-dv-", "-ovLN"]
    opts_lit = ["-ab", "0", "-av", "0", "0", "0", "-dv-", "-dj", "1", "-ds", "0.25",
                "-dt", "0", "-dc", "1", "-dr", "0", "-lr", "0", "-lw", "1e-9", "-ov"]
    opts_sky = ["-ab", "0", "-av", "0", "0", "0", "-ov"]
    t0 = time.time()
    hemi = None
    if oct_emit is not None:
        le1 = ref.rtrace(oct_emit, ["-ab", "0", "-av", "0", "0", "0", "-ov"],
                         np.hstack([org, dirs]), 3, procs)
        hemi = math.pi * le1.reshape(npts, npaths, 3)
    alive = np.arange(len(org))
    depth = 0
    while len(alive) and depth < max_depth:
        rays = np.hstack([org[alive], dirs[alive]])
        a = ref.rtrace(oct_albedo, opts_alb, rays, 7, procs)
        hit = a[:, 3] < 1e9
        if oct_sky is not None and depth > 0 and sky_k == 0 and np.any(~hit):
            ls = ref.rtrace(oct_sky, opts_sky, rays[~hit], 3, procs)
            acc[alive[~hit]] += thr[alive[~hit]] * ls
        alive, a, rays = alive[hit], a[hit], rays[hit]
        if not len(alive):
            break
        lit = ref.rtrace(oct_light, opts_lit, rays, 3, procs)
        acc[alive] += thr[alive] * lit
        rho = a[:, :3]
        p = rays[:, :3] + rays[:, 3:] * a[:, 3:4]
        nn = a[:, 4:7]
        flip = np.einsum("ij,ij->i", nn, rays[:, 3:]) > 0
        nn[flip] *= -1
        thr[alive] *= rho
        if oct_sky is not None and sky_k > 0:
            # sky seen directly from this vertex: sky_k stratified cosine rays
            # (instead of the continuation ray's own escape, which then adds
            # nothing): same expectation, less variance
            live = np.max(thr[alive], axis=1) > 0
            if np.any(live):
                sk = int(round(math.sqrt(sky_k)))
                so, sd = stratified_cosine(p[live] + eps * nn[live], nn[live], sk, rng)
                ls = ref.rtrace(oct_sky, opts_sky, np.hstack([so, sd]), 3, procs)
                acc[alive[live]] += thr[alive[live]] * ls.reshape(-1, sk * sk, 3).mean(axis=1)
        depth += 1
        tmax = np.max(thr[alive], axis=1)
        q = np.clip(tmax / rr, 0.0, 1.0)
        surv = rng.random(len(alive)) < q
        thr[alive[surv]] /= q[surv][:, None]
        alive, p, nn = alive[surv], p[surv], nn[surv]
        org[alive] = p + eps * nn
        dirs[alive] = ref.cosine_dirs(nn, rng.random(len(alive)), rng.random(len(alive)))
        log("  bounce %d: %d paths alive (%.1fs)" % (depth, len(alive), time.time() - t0))
    vals = math.pi * acc.reshape(npts, npaths, 3)
    eind = vals.mean(axis=1)
    se = vals.std(axis=1, ddof=1) / math.sqrt(npaths)
    edir_near = None
    if hemi is not None and np.any(near):
        v2 = vals[near] + hemi[near]
        edir_near = hemi[near].mean(axis=1)
        se[near] = v2.std(axis=1, ddof=1) / math.sqrt(npaths)
    return eind, se, hemi, edir_near


# ------------------------------------------------------------ main
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("points")
    ap.add_argument("out")
    ap.add_argument("--accuracy", choices=["low", "medium", "high"], default="medium")
    ap.add_argument("--sky", choices=["uniform", "overcast", "clear"])
    ap.add_argument("--sky-illuminance", type=float,
                    help="unobstructed horizontal illuminance of the sky alone, lux")
    ap.add_argument("--sun", nargs=3, type=float, metavar=("ALTITUDE", "AZIMUTH", "LUX"))
    ap.add_argument("--emitters", choices=["auto", "illum", "mix", "light"], default="auto")
    ap.add_argument("--paths", type=int, help="override paths per point")
    ap.add_argument("--sky-rays", type=int,
                    help="cosine rays per point for the sky seen directly "
                         "(default 16 x paths, at least 4096)")
    ap.add_argument("--vertex-sky-rays", type=int, default=4,
                    help="cosine rays per path vertex for the sky seen from there "
                         "(a square number; 0: only the continuation ray)")
    ap.add_argument("--point-radius", type=float, default=1e-3,
                    help="radius of the spheres standing for point and spot lights (m)")
    ap.add_argument("--sun-diameter", type=float, default=0.01,
                    help="degrees (0.01: parallel, as the renderer's sun)")
    ap.add_argument("--ground-reflectance", type=float, default=0.2,
                    help="the ground below the horizon, with a sky (gensky's)")
    ap.add_argument("--procs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--offset", type=float, default=1e-4)
    ap.add_argument("--fine-k", type=int, default=16)
    ap.add_argument("--near", type=float, default=0.1)
    ap.add_argument("--fine-budget", type=int, default=1024)
    ap.add_argument("--harness", default=HARNESS, help="the shared reference harness")
    ap.add_argument("--keep", help="keep the Radiance files in this directory")
    ap.add_argument("-q", "--quiet", action="store_true")
    a = ap.parse_args(argv)
    if a.sky and a.sky_illuminance is None:
        ap.error("--sky needs --sky-illuminance")
    if a.sky == "clear" and not a.sun:
        ap.error("--sky clear needs --sun (its position)")
    ref.ENV = ref.radiance_env()
    log = (lambda s: None) if a.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    t_start = time.time()

    scene = obj2rad.parse_obj(a.scene)
    polys = obj2rad.planar_polygons(scene)
    diag = obj2rad.scene_diag(scene)
    lights = parse_light_directives(a.scene)
    if a.sun:
        lights.append(sun_from_angles(*a.sun))
    sky = None
    if a.sky:
        sun_vec = -lights[-1]["dir"] if a.sun else None
        K = sky_horizontal_integral(a.sky, sun_vec)
        lum = a.sky_illuminance / EFFICACY / K
        sun_h = a.sun[2] * math.sin(math.radians(a.sun[0])) if a.sun else 0.0
        ground = a.ground_reflectance * (a.sky_illuminance + sun_h) / math.pi / EFFICACY
        sky = dict(kind=a.sky, sun=sun_vec, K=K, L=np.full(3, lum), ground=np.full(3, ground))
        log("ground: reflectance %g, glow radiance %.6g W/m^2/sr" % (a.ground_reflectance, ground))
        log("sky %s: E_h %.6g lux, shape integral %.9g, glow radiance %.6g W/m^2/sr"
            % (a.sky, a.sky_illuminance, K, lum))
    for L in lights:
        log("light (line %s): %s" % (L["line"], {k: (np.round(v, 6).tolist() if isinstance(v, np.ndarray) else v)
                                                   for k, v in L.items() if k != "line"}))

    if a.sun and a.sun[0] <= 0:
        log("warning: --sun altitude %g <= 0: the sun is at or below the horizon" % a.sun[0])
    # a light's sphere must be clear of every surface (a Lambertian sphere
    # has intensity L pi r^2 exactly; measured: r = 1 mm and 0.1 mm give the
    # same E to 1e-6 at 5 mm under the light)
    tris = [(p[0], p[i], p[i + 1]) for _, p in polys for i in range(1, len(p) - 1)]
    if tris:
        A, B, C = (np.array(t) for t in zip(*tris))
        for L in lights:
            if L["kind"] in ("point", "spot"):
                dmin = ref.point_tri_dist(L["pos"], A, B, C).min()
                if dmin < 3 * a.point_radius:
                    log("warning: light at line %s is %.3g m from a surface (sphere radius "
                        "%.3g m): lower --point-radius" % (L["line"], dmin, a.point_radius))

    emitters = a.emitters
    if emitters == "auto":
        area = {}
        for mat, p in polys:
            area[mat] = area.get(mat, 0.0) + 0.5 * np.linalg.norm(obj2rad.newell_normal(p))
        tot = sum(area.values())
        re_ = sum(v for k, v in area.items() if all(ref.emitter_kind(scene.materials[k])))
        emitters = "illum" if re_ <= 0.2 * tot else "mix"
    has_emit = any(ref.emitter_kind(scene.materials[m])[0] for m, _ in polys)

    work = a.keep or tempfile.mkdtemp(prefix="reflights_")
    os.makedirs(work, exist_ok=True)
    with open(os.path.join(work, "rl_spot.cal"), "w") as fh:
        fh.write(SPOT_CAL)
    with open(os.path.join(work, "rl_sky.cal"), "w") as fh:
        fh.write(SKY_CAL)
    ref.ENV["RAYPATH"] = work + os.pathsep + ref.ENV["RAYPATH"]
    try:
        geo, ng = ref.geometry_text(scene, polys)
        src = lights_text(lights, "source", a.point_radius, a.sun_diameter)
        blk = lights_text(lights, "black", a.point_radius, a.sun_diameter)
        # the sky is not in the main scene: Radiance never samples a distant
        # glow directly, and escaped path rays are traced in sky.oct
        oct_main = ref.oconv(ref.mat_text(scene, "light", emitters) + geo + src,
                             os.path.join(work, "scene.oct"))
        oct_alb = ref.oconv(ref.mat_text(scene, "albedo", emitters) + geo + blk,
                            os.path.join(work, "albedo.oct"))
        oct_lights = ref.oconv(plain_materials(scene) + geo + src,
                               os.path.join(work, "lights.oct")) if lights else None
        oct_sky = ref.oconv(black_materials(scene) + geo + blk + sky_text(sky),
                            os.path.join(work, "sky.oct")) if sky else None
        oct_fine = oct_emit = None
        fine_k = 0
        if has_emit:
            n_emit = sum(1 for mat, _ in polys if ref.emitter_kind(scene.materials[mat])[0])
            fine_k = max(1, min(a.fine_k, int(math.sqrt(a.fine_budget / max(n_emit, 1)))))
            geo_fine, _ = ref.geometry_text(scene, polys, fine_k=fine_k, diag=diag)
            oct_fine = ref.oconv(ref.mat_text(scene, "direct", emitters) + geo_fine,
                                 os.path.join(work, "fine.oct"))
            oct_emit = ref.oconv(ref.mat_text(scene, "emission", emitters) + geo,
                                 os.path.join(work, "emission.oct"))
        log("scene: %d polygons, %d lights, sky %s, emitter faces split %dx%d, emitters=%s"
            % (ng, len(lights), a.sky or "none", fine_k, fine_k, emitters))

        pts = ref.load_points(a.points)
        idx, dist = ref.match_faces(pts, polys, diag)
        if np.any(idx < 0):
            log("warning: %d points matched no face (B = nan)" % int(np.sum(idx < 0)))
        eps = ref.offset_length(polys, a.offset)
        xe = ref.eval_points(pts, idx, polys, eps)
        n = pts[:, 3:]
        near = (ref.near_emitters(xe, n, polys, scene, a.near) if has_emit
                else np.zeros(len(pts), bool))
        if np.any(near):
            log("%d of %d points are near an emitter: direct term from hemisphere rays"
                % (int(near.sum()), len(pts)))
        t = time.time()
        npaths = a.paths or ref.ACC["paths"][a.accuracy]
        npaths = int(round(math.sqrt(npaths))) ** 2
        rng_sky = np.random.default_rng(a.seed + 7919)
        e = np.zeros((len(pts), 3))
        se2 = np.zeros((len(pts), 3))
        if lights:
            el = ref.rtrace(oct_lights, ["-I"] + ref.DIRECT_FINE, ref.irays(xe, n), 3, a.procs)
            e += el
            log("  lights' direct term (rtrace -I -ab 0 -dj 0): %.1fs" % (time.time() - t))
        edir = np.zeros((len(pts), 3))
        if has_emit:
            edir = ref.direct_fine(oct_fine, xe, n, a.procs)
        if sky:
            nsky = a.sky_rays or max(16 * npaths, 4096)
            es, ses = sky_direct(oct_sky, xe, n, nsky, a.procs, rng_sky, log)
            e += es
            se2 += ses ** 2
        per = max(1, 2_000_000 // npaths)
        check = []
        for c0 in range(0, len(pts), per):
            sl = slice(c0, c0 + per)
            if len(pts) > per:
                log("points %d-%d of %d" % (c0, min(c0 + per, len(pts)), len(pts)))
            eind, sei, hemi, edn = paths_lights(oct_main, oct_alb, oct_emit, oct_sky, xe[sl],
                                                n[sl], near[sl], npaths, a.procs,
                                                a.seed + c0, diag, log,
                                                sky_k=a.vertex_sky_rays)
            if edn is not None:
                ed = edir[sl]
                ed[near[sl]] = edn
                edir[sl] = ed
            if hemi is not None:
                far = ~near[sl]
                check.append((hemi[far].mean(axis=1).sum(1), edir[sl][far].sum(1),
                              hemi[far].std(axis=1, ddof=1).sum(1) / math.sqrt(npaths)))
            e[sl] += eind
            se2[sl] += sei ** 2
        e += edir
        se = np.sqrt(se2)
        if check:
            eh = np.concatenate([c[0] for c in check])
            ed = np.concatenate([c[1] for c in check])
            sh_ = np.concatenate([c[2] for c in check])
            ok = ed > 0
            if np.any(ok):
                log("  check: emitters' direct term, hemisphere rays vs subdivided sources, "
                    "%d points: relative difference of sums %+.2e (1-sigma noise %.1e)"
                    % (ok.sum(), np.sum(eh[ok] - ed[ok]) / np.sum(ed[ok]),
                       math.sqrt(np.sum(sh_[ok] ** 2)) / np.sum(ed[ok])))
        desc = "paths %d/point" % npaths
        if sky:
            desc += ", sky rays %d/point" % int(round(math.sqrt(nsky))) ** 2
        t_calc = time.time() - t
    finally:
        if not a.keep:
            shutil.rmtree(work, ignore_errors=True)

    kd = np.full((len(pts), 3), np.nan)
    ke = np.full((len(pts), 3), np.nan)
    names = []
    for k in range(len(pts)):
        if idx[k] >= 0:
            m = scene.materials[polys[idx[k]][0]]
            kd[k], ke[k] = m["Kd"], m["Ke"]
            names.append(polys[idx[k]][0])
        else:
            names.append("-")
    b = ke + kd * e
    total = time.time() - t_start
    with open(a.out, "w") as fh:
        fh.write("# reference_lights.py %s %s method=paths (%s) accuracy=%s emitters=%s seed=%d\n"
                 % (a.scene, a.points, desc, a.accuracy, emitters, a.seed))
        fh.write("# lights: %d from #@light%s; sky: %s\n"
                 % (len(lights) - (1 if a.sun else 0),
                    (", --sun %g %g %g" % tuple(a.sun)) if a.sun else "",
                    ("%s %g lux" % (a.sky, a.sky_illuminance)) if a.sky else "none"))
        fh.write("# %d points, calc %.1fs, total %.1fs, procs %d\n"
                 % (len(pts), t_calc, total, a.procs))
        fh.write("# Er Eg Eb  Br Bg Bb  sEr sEg sEb  material\n")
        for k in range(len(pts)):
            fh.write("%.7g %.7g %.7g  %.7g %.7g %.7g  %.3g %.3g %.3g  %s\n"
                     % (tuple(e[k]) + tuple(b[k]) + tuple(se[k]) + (names[k],)))
    log("done: %d points, %s, calc %.1fs, total %.1fs" % (len(pts), desc, t_calc, total))
    return e, b, se


if __name__ == "__main__":
    main()
