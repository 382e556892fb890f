# SPDX-License-Identifier: GPL-3.0-or-later
"""What the Blender add-on costs on top of the command line: the wall time
of ``bpy.ops.radiosity.bake()`` (checks, UV maps, glTF export, the solve,
reading the lightmap back and wiring it; Blender's start-up excluded)
against the same ``radiosity render`` command on the file it exported,
side by side, alternating, median of N runs each. Each run bakes twice and
counts the second (a re-bake, the UV maps made), printing both and the
parts of each (prepare: checks, UV maps and export; apply: the image and
the nodes).

Run (bpy installed, e.g. by .ci/blender-tests):
  RADIOSITY_BIN=target/release/radiosity target/bpy-venv/bin/python \\
      blender/bench_overhead.py [RUNS] [SCENE.obj TIME_LIMIT]

With an OBJ file, that scene is imported into Blender (its own lights
none: a sun is added) instead of the test's room, and both solves stop at
TIME_LIMIT seconds, so the difference is the add-on's own work on a big
scene: the first bake packs every object's Lightmap UV map.
"""

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import bpy

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from test_bake import build_scene

import radiosity_bake
from radiosity_bake import job as bake_job


def imported(path):
    """An empty scene holding the OBJ at `path` and a sun."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=path)
    scene = bpy.context.scene
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = 5.0
    sun_obj = bpy.data.objects.new("sun", sun)
    sun_obj.rotation_euler = (0.5, 0.2, 0.3)
    scene.collection.objects.link(sun_obj)
    return scene


def main():
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    obj = sys.argv[2] if len(sys.argv) > 2 else None
    limit = float(sys.argv[3]) if len(sys.argv) > 3 else 0.0
    binary = os.environ.get("RADIOSITY_BIN") or str(ROOT.parent / "target/release/radiosity")
    os.environ["RADIOSITY_BIN"] = binary
    radiosity_bake.register()
    addon, cli = [], []
    for _ in range(runs):
        scene = build_scene() if obj is None else imported(obj)
        folder = tempfile.mkdtemp(prefix="radiosity-overhead-")
        settings = scene.radiosity_bake
        settings.work_folder = folder
        settings.device = "cpu"
        settings.time_limit = limit
        for bake_number in (1, 2):
            # The first bake packs the Lightmap UV maps; a second finds them.
            start = time.perf_counter()
            bake = bake_job.Job(bpy.context)
            bake.run(report=lambda _: None)
            wall = time.perf_counter() - start
            parts = ", ".join(f"{k} {v:.2f} s" for k, v in bake.timings.items())
            print(f"bake {bake_number}: {wall:.2f} s ({parts})", flush=True)
        addon.append(wall)
        sky = bake_job.prepare.world_sky(scene, [])
        out = os.path.join(folder, "cli")
        os.makedirs(out)
        command = bake_job.settings_command(
            binary, settings, scene, os.path.join(folder, "scene.glb"), out, sky
        )
        start = time.perf_counter()
        subprocess.run(command + ["-q"], check=True)
        cli.append(time.perf_counter() - start)
        print(f"run: add-on {addon[-1]:.2f} s, command line {cli[-1]:.2f} s", flush=True)
    a, c = statistics.median(addon), statistics.median(cli)
    print(f"add-on bake: {', '.join(f'{t:.2f}' for t in addon)} s, median {a:.2f} s")
    print(f"command line on its export: {', '.join(f'{t:.2f}' for t in cli)} s, median {c:.2f} s")
    print(f"add-on overhead: {a - c:+.2f} s (median against median)")


if __name__ == "__main__":
    main()
    # bpy 4.2.23 as a module crashes at exit after a glTF export (see
    # tests/test_bake.py, exit_now).
    sys.stdout.flush()
    os._exit(0)
