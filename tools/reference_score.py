#!/usr/bin/env python3
"""Helper of `radiosity experiment validate` and `accuracy-curve`, which write
it beside their outputs and run it with the reference harness's Python
(/tmp/refvenv). It drives the shared Radiance reference harness
(../shared/reference) without changing it and answers in JSON.

  reference_score.py score HARNESS SCENE.obj VERTICES.csv OUT.json
                     [--n N] [--accuracy A]
                     [--lights-script reference_lights.py --lights-args=FLAGS]
      Runs the harness's own score.py on a vertices CSV inside this process
      (its code unchanged, so the sample, the cached reference and every
      number are score.py's) and writes the points it sampled, their
      reference radiosity and score.py's numbers. With --lights-script, the
      reference is computed by that script (lights that are not surfaces:
      #@light, and FLAGS such as --sun and --sky) instead of reference.py,
      cached in a folder of its own. The same option runs any other script
      with reference.py's command line in its place (reference_edges.py:
      points on a face's edge moved off it), with --lights-args= empty.

  reference_score.py radiance HARNESS SCENE.obj POINTS.txt OUT.json
                     --procs P RUN [RUN ...]
      Converts the scene with the harness's obj2rad.py (emitters as Radiance
      `light`s), moves the points as reference.py does (off edges, along the
      normal, compensating rtrace's own offset) and times `rtrace -I -n P`
      once per RUN ("name|rtrace options"). POINTS.txt: x y z nx ny nz face
      per line; B = Ke + Kd E with the face's material, as score.py takes it.
"""
import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import time


def score(a):
    path = os.path.join(a.harness, "score.py")
    argv = [path, a.scene, a.csv, "1e9", "--n", str(a.n), "--accuracy", a.accuracy]
    if a.lights_script:
        # Scenes with lights that are not surfaces (#@light, --sun, --sky):
        # score.py runs reference_lights.py instead of reference.py, with
        # the daylight options, and caches in a folder of their own.
        import hashlib
        import shlex
        import subprocess
        extra = shlex.split(a.lights_args or "") + ["--harness", a.harness]
        key = hashlib.sha1((open(a.lights_script).read() + repr(extra)).encode()).hexdigest()
        base = os.environ.get("REFCACHE", "/tmp/reference-cache")
        os.environ["REFCACHE"] = os.path.join(base, "lights-" + key[:12])
        real_run = subprocess.run

        def run(cmd, *args, **kwargs):
            if len(cmd) > 1 and str(cmd[1]).endswith("reference.py"):
                cmd = [cmd[0], a.lights_script] + list(cmd[2:]) + extra
            return real_run(cmd, *args, **kwargs)

        subprocess.run = run
    g = {"__name__": "__main__", "__file__": path}
    saved = sys.argv
    sys.argv = argv
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            exec(compile(open(path).read(), path, "exec"), g)
    except SystemExit:
        pass
    finally:
        sys.argv = saved
    text = printed.getvalue()
    if "l1" not in g:
        sys.stderr.write(text)
        last = text.strip().splitlines()[-1] if text.strip() else "no output"
        sys.exit("score.py did not finish: " + last)
    np = g["np"]
    rel = g["rel"]
    with open(g["out"]) as fh:
        header = [line.rstrip("\n") for line in fh if line.startswith("#")]
    bref = [None if not np.isfinite(r).all() else [float(x) for x in r] for r in g["Bref"]]
    result = {
        "idx": [int(i) for i in g["idx"]],
        "bref": bref,
        "l1": float(g["l1"]),
        "bias": float(g["bias"]),
        "median": float(np.median(rel)),
        "p90": float(np.percentile(rel, 90)),
        "points": int(g["ok"].sum()),
        "noise": float(g["noise"]),
        "printed": text,
        "reference_header": header,
        "cache": g["out"],
    }
    with open(a.out, "w") as fh:
        json.dump(result, fh)


def radiance(a):
    sys.path.insert(0, a.harness)
    import numpy as np
    import obj2rad
    import reference

    reference.ENV = reference.radiance_env()
    rows = np.loadtxt(a.points, ndmin=2)
    pts = rows[:, :6].copy()
    pts[:, 3:] /= np.linalg.norm(pts[:, 3:], axis=1)[:, None]
    faces = rows[:, 6].astype(int)
    text, scene, polys, _ = obj2rad.convert(a.scene, "light")
    kd = np.array([scene.materials[scene.faces[f][0]]["Kd"] for f in faces])
    ke = np.array([scene.materials[scene.faces[f][0]]["Ke"] for f in faces])
    runs = []
    with tempfile.TemporaryDirectory() as work:
        octree = reference.oconv(text, os.path.join(work, "scene.oct"))
        diag = obj2rad.scene_diag(scene)
        idx, _ = reference.match_faces(pts, polys, diag)
        eps = reference.offset_length(polys, 1e-4)
        xe = reference.eval_points(pts, idx, polys, eps)
        rays = reference.irays(xe, pts[:, 3:])
        for spec in a.runs:
            name, options = spec.split("|", 1)
            start = time.perf_counter()
            e = reference.rtrace(octree, ["-I"] + options.split(), rays, 3, a.procs)
            seconds = time.perf_counter() - start
            b = ke + kd * e
            runs.append({"name": name, "options": options, "seconds": seconds,
                         "e": e.tolist(), "b": b.tolist()})
            print("  %s: %.1f s" % (name, seconds), file=sys.stderr)
    with open(a.out, "w") as fh:
        json.dump({"runs": runs}, fh)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="mode", required=True)
    s = sub.add_parser("score")
    for name in ("harness", "scene", "csv", "out"):
        s.add_argument(name)
    s.add_argument("--n", type=int, default=600)
    s.add_argument("--accuracy", default="high")
    s.add_argument("--lights-script", help="reference_lights.py, for scenes with lights")
    s.add_argument("--lights-args", help="its daylight options, one string")
    r = sub.add_parser("radiance")
    for name in ("harness", "scene", "points", "out"):
        r.add_argument(name)
    r.add_argument("--procs", type=int, default=2)
    r.add_argument("runs", nargs="+")
    a = ap.parse_args()
    score(a) if a.mode == "score" else radiance(a)


if __name__ == "__main__":
    main()
