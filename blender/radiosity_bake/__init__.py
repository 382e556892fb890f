# SPDX-License-Identifier: GPL-3.0-or-later
"""Radiosity Bake: diffuse global illumination baked into lightmaps from
inside Blender, by the radiosity program (progressive radiosity after
Wallace, Elmquist & Haines 1989 and Wong & Tsang 1993).

A panel in the Render properties holds the settings and the Bake button
(``bpy.ops.radiosity.bake()``); the add-on's preferences name the program.
With a window the bake runs in the background, its progress in the status
bar, Esc stopping it with the light reached and a second Esc abandoning it;
without one (``blender -b``, ``bpy`` as a module) the operator waits for it.
See :mod:`.job` for the steps.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, PointerProperty, StringProperty

from . import apply, job
from .prepare import BakeError

PRESETS = [
    (
        "adaptive",
        "Adaptive",
        "The default: element-resolution shooting, refined meshes, final pass",
    ),
    ("wong-tsang93", "Wong & Tsang 1993", "The paper's method, on the CPU"),
    ("wallace89", "Wallace et al. 1989", "Ray-traced form factors, on the CPU"),
]
FINAL_GATHER = [
    ("direct", "Direct", "Direct light evaluated at every texel, indirect from the mesh (default)"),
    ("off", "Off", "The mesh's values, interpolated"),
    ("full", "Full", "Also the indirect light gathered over each texel's hemisphere (slow)"),
]
DEVICES = [
    ("auto", "Auto", "A real GPU when there is one, else the CPU"),
    ("cpu", "CPU", "The CPU"),
    ("gpu", "GPU", "The GPU (an error without one)"),
]
LOOKS = [
    ("LIT", "Lit", "The lightmap as emission: the solved light exactly, as a game engine shows it"),
    (
        "SHADING",
        "Keep shading",
        "The lightmap (irradiance) times each material's base colour and texture, as emission",
    ),
]


class RadiosityBakeSettings(bpy.types.PropertyGroup):
    """A scene's bake settings."""

    preset: EnumProperty(name="Preset", items=PRESETS, default="adaptive")
    time_limit: FloatProperty(
        name="Time limit",
        description="Stop the solve after this many seconds (0: when it converges)",
        default=0.0,
        min=0.0,
        unit="TIME_ABSOLUTE",
    )
    density: FloatProperty(
        name="Texel density",
        description="Lightmap texels per metre of surface",
        default=32.0,
        min=0.5,
        max=4096.0,
    )
    final_gather: EnumProperty(name="Final gather", items=FINAL_GATHER, default="direct")
    device: EnumProperty(name="Device", items=DEVICES, default="auto")
    look: EnumProperty(name="Look", items=LOOKS, default="LIT")
    world_as_sky: BoolProperty(
        name="World as sky",
        description="Bake the World's colour as a uniform sky of the same luminance",
        default=True,
    )
    apply_modifiers: BoolProperty(
        name="Apply modifiers on copies",
        description=(
            "Bake objects whose modifiers change their topology from copies with the modifiers "
            "applied, shown in their place (else they are refused)"
        ),
        default=False,
    )
    single_user: BoolProperty(
        name="Make single-user copies",
        description="Give objects sharing a mesh a copy each (else they are refused)",
        default=False,
    )
    extra_arguments: StringProperty(
        name="Extra arguments",
        description=(
            "More flags for 'radiosity render', as on its command line (e.g. --converge 0.001 "
            "--element-size 0.05)"
        ),
        default="",
    )
    work_folder: StringProperty(
        name="Keep files in",
        description=(
            "Folder for the exported scene, the bake, its picture and log (empty: a temporary "
            "folder, removed afterwards)"
        ),
        default="",
        subtype="DIR_PATH",
    )


class RadiosityBakePreferences(bpy.types.AddonPreferences):
    """Where the radiosity program is."""

    bl_idname = __package__

    binary: StringProperty(
        name="radiosity program",
        description="The radiosity program (empty: RADIOSITY_BIN, then PATH)",
        default="",
        subtype="FILE_PATH",
    )

    def draw(self, context):
        self.layout.prop(self, "binary")


def binary_preference(context):
    """The program named in the preferences, if the add-on has them."""
    addon = context.preferences.addons.get(__package__)
    return addon.preferences.binary if addon and addon.preferences else ""


class RADIOSITY_OT_bake(bpy.types.Operator):
    """Solve the scene's diffuse light by radiosity and bake it into a lightmap on every
    render-enabled mesh"""

    bl_idname = "radiosity.bake"
    bl_label = "Bake Radiosity"
    bl_options = {"REGISTER"}  # noqa: RUF012 (Blender reads it)

    _job = None
    _timer = None
    _escapes = 0

    def execute(self, context):
        bake = job.Job(context, binary_preference(context))
        try:
            result = bake.run(report=lambda line: print(line, flush=True))
        except (BakeError, OSError, ReferenceError) as e:
            self.report({"ERROR"}, f"Radiosity bake: {e}")
            return {"CANCELLED"}
        self._report_done(bake, result)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        bake = job.Job(context, binary_preference(context))
        try:
            bake.start()
        except (BakeError, OSError, ReferenceError) as e:
            self.report({"ERROR"}, f"Radiosity bake: {e}")
            return {"CANCELLED"}
        self._job = bake
        self._escapes = 0
        wm = context.window_manager
        self._timer = wm.event_timer_add(job.POLL_SECONDS, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 1000)
        context.workspace.status_text_set(bake.solve.status())
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        bake = self._job
        if event.type == "ESC" and event.value == "PRESS":
            self._escapes += 1
            if self._escapes == 1:
                bake.request_stop()
                self.report({"INFO"}, "Radiosity: stopping; the light reached will be baked")
            else:
                bake.abandon()
                self._end(context)
                self.report({"WARNING"}, "Radiosity bake abandoned: nothing was changed")
                return {"CANCELLED"}
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        if not bake.poll():
            context.workspace.status_text_set(bake.solve.status())
            context.window_manager.progress_update(int(1000 * bake.solve.completion()))
            return {"RUNNING_MODAL"}
        self._end(context)
        try:
            result = bake.finish()
        except (BakeError, OSError, ReferenceError) as e:
            self.report({"ERROR"}, f"Radiosity bake: {e}")
            return {"CANCELLED"}
        self._report_done(bake, result)
        return {"FINISHED"}

    def _end(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        context.workspace.status_text_set(None)

    def _report_done(self, bake, result):
        for warning in bake.warnings:
            self.report({"WARNING"}, f"Radiosity: {warning}")
        stopped = result["stop_reason"] in ("stopped", "time-limit")
        self.report(
            {"INFO"},
            f"Radiosity: baked {result['objects']} objects ({result['materials']} materials), "
            f"{result['shots']} shots, unshot {100 * (result['unshot_fraction'] or 0):.2f}%"
            + (" (stopped early)" if stopped else "")
            + f", {bake.timings['total']:.1f} s",
        )


class RADIOSITY_OT_clear(bpy.types.Operator):
    """Take the baked lightmap out of every material, restoring their previous surfaces"""

    bl_idname = "radiosity.clear"
    bl_label = "Remove Radiosity Lightmap"
    bl_options = {"REGISTER", "UNDO"}  # noqa: RUF012 (Blender reads it)

    def execute(self, context):
        restored = apply.clear()
        self.report({"INFO"}, f"Radiosity: {restored} materials restored")
        return {"FINISHED"}


class RENDER_PT_radiosity_bake(bpy.types.Panel):
    """The bake's settings and button, in the Render properties."""

    bl_label = "Radiosity Bake"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        settings = context.scene.radiosity_bake
        layout = self.layout
        layout.use_property_split = True
        layout.prop(settings, "preset")
        layout.prop(settings, "time_limit")
        layout.prop(settings, "density")
        row = layout.row()
        row.enabled = settings.preset == "adaptive"
        row.prop(settings, "final_gather")
        layout.prop(settings, "device")
        layout.prop(settings, "look")
        layout.prop(settings, "world_as_sky")
        layout.prop(settings, "apply_modifiers")
        layout.prop(settings, "single_user")
        layout.prop(settings, "extra_arguments")
        layout.prop(settings, "work_folder")
        layout.operator(RADIOSITY_OT_bake.bl_idname, icon="LIGHT_SUN")
        layout.operator(RADIOSITY_OT_clear.bl_idname, icon="X")


CLASSES = (
    RadiosityBakeSettings,
    RadiosityBakePreferences,
    RADIOSITY_OT_bake,
    RADIOSITY_OT_clear,
    RENDER_PT_radiosity_bake,
)


def register():
    """Registers the add-on's classes and the scene's settings."""
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.radiosity_bake = PointerProperty(type=RadiosityBakeSettings)


def unregister():
    """Removes what :func:`register` added."""
    del bpy.types.Scene.radiosity_bake
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
