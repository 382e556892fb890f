#!/usr/bin/env python3
"""Closed-form (or numerically integrated) irradiance for the cases written
by make_cases.py, compared with an OUT.txt of reference_lights.py.

usage: check_cases.py CASE OUT.txt [sky options as given to reference_lights.py]
  CASE: floor_point | floor_spot | floor_sun | floor_open | skylight_room | big_floor
"""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def sky_shape(kind, d, sun=None):
    dy = d[..., 1]
    if kind == "uniform":
        return np.where(dy > 0, 1.0, 0.0)
    if kind == "overcast":
        return np.where(dy > 0, (1 + 2 * dy) / 3, 0.0)
    cg = np.clip(d @ sun, -1, 1)
    with np.errstate(divide="ignore", over="ignore"):
        z = 1 - np.exp(-0.32 / np.where(dy > 0, dy, 1))
    return np.where(dy > 0, (0.91 + 10 * np.exp(-3 * np.arccos(cg)) + 0.45 * cg * cg) * z, 0.0)


def sky_norm(kind, sun):
    """sky radiance scale so that E_h = 1 W/m^2: independent quadrature
    (Gauss-Legendre in theta, midpoint in phi)."""
    x, w = np.polynomial.legendre.leggauss(600)
    th = (x + 1) * math.pi / 4
    wt = w * math.pi / 4
    ph = (np.arange(2400) + 0.5) / 2400 * 2 * math.pi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(T) * np.sin(P), np.cos(T), -np.sin(T) * np.cos(P)], -1)
    f = sky_shape(kind, d, sun) * np.cos(T) * np.sin(T)
    return 1.0 / ((f * wt[:, None]).sum() * 2 * math.pi / 2400)


def polygon_view_factor(x, n, poly):
    """Exact view factor from a differential area (x, normal n) to a planar
    polygon (Lambert's contour formula), the polygon first clipped to the
    receiver's front half-space."""
    P = [np.asarray(p, float) - x for p in poly]
    out = []
    for i in range(len(P)):
        a, b = P[i], P[(i + 1) % len(P)]
        da, db = a @ n, b @ n
        if da > 0:
            out.append(a)
        if (da > 0) != (db > 0):
            out.append(a + (b - a) * (da / (da - db)))
    f = 0.0
    for i in range(len(out)):
        a, b = out[i], out[(i + 1) % len(out)]
        c = np.cross(a, b)
        ang = math.atan2(np.linalg.norm(c), a @ b)
        f += ang * (c @ n) / np.linalg.norm(c)
    return abs(f) / (2 * math.pi)


def sky_on_plane(kind, n, sun):
    """int over y > 0 of shape(d) max(0, d.n) dw (Gauss-Legendre x midpoint)."""
    x, w = np.polynomial.legendre.leggauss(1500)
    th = (x + 1) * math.pi / 4
    wt = w * math.pi / 4
    nph = 6000
    ph = (np.arange(nph) + 0.5) / nph * 2 * math.pi
    tot = 0.0
    for k in range(0, len(th), 100):
        T, P = np.meshgrid(th[k:k + 100], ph, indexing="ij")
        d = np.stack([np.sin(T) * np.sin(P), np.cos(T), -np.sin(T) * np.cos(P)], -1)
        f = sky_shape(kind, d, sun) * np.clip(d @ n, 0, None) * np.sin(T)
        tot += (f * wt[k:k + 100, None]).sum() * 2 * math.pi / nph
    return tot


def main():
    case, out = sys.argv[1], sys.argv[2]
    opts = sys.argv[3:]
    pts = np.loadtxt(os.path.join(HERE, case + ".pts"))
    got = np.loadtxt(out, comments="#", usecols=range(9))
    x = pts[:, :3]
    if case == "floor_point":
        d = np.linalg.norm(x - [0.3, 2, -0.2], axis=1)
        exp = (150 / 179 * 2 / d ** 3)[:, None] * np.ones(3)
    elif case == "floor_spot":
        v = x - [0, 2, 0]
        d = np.linalg.norm(v, axis=1)
        c = -v[:, 1] / d
        ci, co = math.cos(math.radians(20)), math.cos(math.radians(35))
        f = np.clip((c - co) / (ci - co), 0, 1) ** 2
        exp = (200 / 179 * f * c / d ** 2)[:, None] * np.array([1, 0.8, 0.6])
    elif case == "floor_sun":
        dv = np.array([0.37, -1, 0.13])
        dv /= np.linalg.norm(dv)
        s = x + (1 / -dv[1]) * -dv          # where the ray to the sun is at y = 1
        lit = ~((np.abs(s[:, 0]) < 0.2) & (np.abs(s[:, 2]) < 0.2))
        exp = (60000 / 179 * -dv[1] * lit)[:, None] * np.ones(3)
    elif case in ("floor_open", "skylight_room", "big_floor"):
        kind = opts[opts.index("--sky") + 1]
        eh = float(opts[opts.index("--sky-illuminance") + 1]) / 179
        sun = None
        esun = 0.0
        if "--sun" in opts:
            k = opts.index("--sun")
            alt, az, lux = (float(t) for t in opts[k + 1:k + 4])
            a, z = math.radians(alt), math.radians(az)
            sun = np.array([math.sin(z) * math.cos(a), math.sin(a), -math.cos(z) * math.cos(a)])
            esun = lux / 179 * math.sin(a)
        scale = eh * sky_norm(kind, sun)
        if case == "floor_open":
            e = np.full(len(x), eh + esun)
        elif case == "big_floor":
            # floor (Kd 0.5) irradiance E_h + E_sun everywhere (nothing blocks);
            # receiver: sky directly + 0.5 (E_h + E_sun) x view factor to the floor
            if esun:
                sys.exit("big_floor with a sun: not handled here")
            floor = [(-100, 0, -100), (-100, 0, 100), (100, 0, 100), (100, 0, -100)]
            nn = pts[:, 3:] / np.linalg.norm(pts[:, 3:], axis=1)[:, None]
            e = np.array([scale * sky_on_plane(kind, m, sun)
                          + 0.5 * eh * polygon_view_factor(p, m, floor)
                          for p, m in zip(x, nn)])
        else:
            if esun:
                sys.exit("sun through the skylight: not handled here")
            # sky through the 1x1 hole at y = 3: int L(dir) cos_r cos_a / d^2 dA
            n = 2000
            u = (np.arange(n) + 0.5) / n - 0.5
            U, V = np.meshgrid(u, u, indexing="ij")
            e = []
            for p in x:
                r = np.stack([U - p[0], np.full_like(U, 3 - p[1]), V - p[2]], -1)
                d2 = (r * r).sum(-1)
                dirs = r / np.sqrt(d2)[..., None]
                cs = dirs[..., 1]
                e.append((sky_shape(kind, dirs, sun) * cs * cs / d2).sum() / n / n * scale)
            e = np.array(e)
        exp = e[:, None] * np.ones(3)
    else:
        sys.exit("unknown case")
    print("%-28s %12s %12s %9s %7s" % ("point", "expected E", "got E", "rel.diff", "z"))
    for p, ex, g in zip(pts, exp, got):
        gm, em, sg = g[:3].mean(), ex.mean(), g[6:9].mean()
        rel = (gm - em) / em if em > 0 else float("nan")
        z = (gm - em) / sg if sg > 0 else float("nan")
        print("(%6.3f %6.3f %6.3f)       %12.6g %12.6g %+9.2e %7.2f" % (tuple(p[:3]) + (em, gm, rel, z)))
        if np.any(ex > 0):
            chan = g[:3] / np.where(ex > 0, ex, 1)
            if np.ptp(chan[ex > 0]) > 1e-3:
                print("     per channel got/expected:", chan)


if __name__ == "__main__":
    main()
