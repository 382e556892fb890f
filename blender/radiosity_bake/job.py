# SPDX-License-Identifier: GPL-3.0-or-later
"""One bake from start to end: the scene prepared and exported
(:mod:`.prepare`), the radiosity program run on it (:mod:`.solve`), the
lightmap brought back (:mod:`.apply`). The operator drives a :class:`Job`
from a timer when Blender has a window, and :meth:`Job.run` waits for it
when it has none (``blender -b``, ``bpy`` as a module).
"""

import os
import shlex
import shutil
import tempfile
import time

import bpy

from . import apply, prepare, solve
from .prepare import BakeError

#: How often the program's progress is read.
POLL_SECONDS = 0.1


def settings_command(binary, settings, scene, glb, folder, sky_lux):
    """The command line for `settings` (the scene's ``radiosity_bake``)."""
    look = settings.look
    command = [
        binary,
        "render",
        glb,
        "--bake",
        os.path.join(folder, "baked.glb"),
        "--bake-target",
        "lightmap",
        "--bake-mode",
        "lit" if look == "LIT" else "irradiance",
        "--lightmap-density",
        repr(float(settings.density)),
        "--stats",
        os.path.join(folder, "stats.json"),
        "-o",
        os.path.join(folder, "picture.png"),
        "--width",
        str(max(1, scene.render.resolution_x * scene.render.resolution_percentage // 100)),
        "--height",
        str(max(1, scene.render.resolution_y * scene.render.resolution_percentage // 100)),
        "--preset",
        settings.preset,
        "--device",
        settings.device,
    ]
    if settings.preset == "adaptive":
        command += ["--final-gather", settings.final_gather]
    if settings.time_limit > 0:
        command += ["--time-limit", repr(float(settings.time_limit))]
    if sky_lux:
        command += ["--sky", "uniform", "--sky-illuminance", repr(sky_lux)]
    try:
        command += shlex.split(settings.extra_arguments)
    except ValueError as e:
        raise BakeError(f"Extra arguments: {e}") from e
    return command


class Job:
    """A bake of the context's scene with its ``radiosity_bake`` settings,
    started by :meth:`start`."""

    def __init__(self, context, binary_preference=""):
        self.context = context
        self.scene = context.scene
        self.settings = context.scene.radiosity_bake
        self.binary_preference = binary_preference
        self.changes = prepare.Changes()
        self.warnings = []
        self.objects = []
        self.solve = None
        self.folder = None
        self.temporary = False
        self.started = None
        self.timings = {}
        self.result = None

    def start(self):
        """Checks and prepares the scene, exports it and starts the program;
        a :class:`BakeError` leaves the scene as it was."""
        self.started = time.perf_counter()
        try:
            self._start()
        except BaseException:
            self.changes.undo()
            self._remove_folder()
            raise

    def _start(self):
        binary = solve.find_binary(self.binary_preference)
        context, settings = self.context, self.settings
        if context.mode != "OBJECT" and context.view_layer.objects.active is not None:
            bpy.ops.object.mode_set(mode="OBJECT")
        objects = prepare.mesh_objects(context)
        if not objects:
            raise BakeError("there is no render-enabled mesh object to bake")
        lights = prepare.light_objects(context)
        sky_lux = prepare.world_sky(self.scene, self.warnings) if settings.world_as_sky else None
        if not prepare.has_light(objects, lights, sky_lux):
            raise BakeError(
                "nothing lights the scene: add a lamp, give a material an emission, or give "
                "the World a colour (with 'World as sky' ticked)"
            )
        objects = prepare.check_objects(
            context, objects, settings.apply_modifiers, settings.single_user, self.changes
        )
        prepare.default_material(objects, self.changes)
        prepare.ensure_lightmap_uvs(objects, settings.density, self.changes)
        self.objects = objects
        if settings.work_folder:
            self.folder = bpy.path.abspath(settings.work_folder)
            os.makedirs(self.folder, exist_ok=True)
            for name in ("stop", "progress.jsonl"):
                path = os.path.join(self.folder, name)
                if os.path.exists(path):
                    os.remove(path)
        else:
            self.folder = tempfile.mkdtemp(prefix="radiosity-bake-")
            self.temporary = True
        glb = os.path.join(self.folder, "scene.glb")
        t = time.perf_counter()
        with apply.original_surfaces(objects):
            self.warnings += prepare.export(context, glb, objects, lights)
        self.timings["export"] = time.perf_counter() - t
        command = settings_command(binary, settings, self.scene, glb, self.folder, sky_lux)
        self.timings["prepare"] = time.perf_counter() - self.started
        self.solve = solve.Solve(command, self.folder)

    def poll(self):
        """Reads the program's progress; True once it has ended."""
        return self.solve.poll()

    def request_stop(self):
        """Stops the solve; the light reached is still brought back."""
        self.solve.request_stop()

    def abandon(self):
        """Kills the program and undoes the preparation: nothing is
        applied."""
        try:
            if self.solve is not None:
                self.solve.abandon()
        finally:
            self.changes.undo()
            self._remove_folder()

    def finish(self):
        """Brings the light back once the program has ended; on failure
        undoes the preparation and raises :class:`BakeError`."""
        try:
            done = self.solve.finish()
            t = time.perf_counter()
            bake = os.path.join(self.folder, "baked.glb")
            exr = next(
                (p for p in done.get("written", []) if p.endswith(".lightmap.exr")),
                os.path.join(self.folder, "baked.lightmap.exr"),
            )
            if not os.path.isabs(exr):
                exr = os.path.join(self.folder, exr)
            materials = apply.apply(self.objects, bake, exr, self.settings.look)
            self.timings["apply"] = time.perf_counter() - t
        except BaseException:
            self.changes.undo()
            self._remove_folder()
            raise
        self.changes.keep()
        self.warnings += done.get("warnings", [])
        self.timings["total"] = time.perf_counter() - self.started
        self.timings["program"] = self.solve.seconds or 0.0
        # The add-on's own share: all but the program's run.
        self.timings["add-on"] = self.timings["total"] - self.timings["program"]
        self.result = {
            "objects": len(self.objects),
            "materials": materials,
            "shots": done.get("shots"),
            "unshot_fraction": done.get("unshot_fraction"),
            "stop_reason": done.get("stop_reason"),
            "solve_s": done.get("solve_s"),
            "folder": None if self.temporary else self.folder,
        }
        self._remove_folder()
        return self.result

    def run(self, report=print):
        """Start to end, waiting for the program (no window needed);
        `report` is called with a progress line now and then."""
        self.start()
        last = 0.0
        try:
            while not self.poll():
                now = time.perf_counter()
                if now - last >= 1.0:
                    report(self.solve.status())
                    last = now
                time.sleep(POLL_SECONDS)
        except BaseException:
            self.abandon()
            raise
        return self.finish()

    def _remove_folder(self):
        if self.temporary and self.folder and os.path.isdir(self.folder):
            shutil.rmtree(self.folder, ignore_errors=True)
