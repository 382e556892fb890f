"""Export the built-in Cornell box from Blender as glTF, the way a Blender
user would hand a scene to radiosity: tests/data/blender-cornell.glb.

Imports crates/radiosity/scenes/cornell.obj with Blender's own OBJ importer, gives every
material a Principled BSDF (Base Color = the MTL's Kd, metallic 0) and the
light an Emission of colour (17, 12, 4) / 17 and strength 17 (radiance in
W/(m^2 sr), the mapping radiosity's README documents: exitance = pi x
strength x colour), adds the OBJ's camera (#@camera), and exports with
Blender's bundled glTF exporter (io_scene_gltf2), +Y up.

Run (from the repository root; needs Debian's `blender` package):
  blender -b --factory-startup --python tools/blender_cornell.py
The committed .glb is what crates/radiosity/tests/gltf.rs reads; CI needs no
Blender.
"""

import math
from pathlib import Path

import bpy

ROOT = Path(__file__).resolve().parent.parent
OBJ = ROOT / "crates" / "radiosity" / "scenes" / "cornell.obj"
OUT = ROOT / "tests" / "data" / "blender-cornell.glb"

KD = {
    "white": (0.725, 0.71, 0.68),
    "red": (0.63, 0.065, 0.05),
    "green": (0.14, 0.45, 0.091),
    "light": (0.78, 0.78, 0.78),
}
RADIANCE = (17.0, 12.0, 4.0)

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.wm.obj_import(filepath=str(OBJ), forward_axis="NEGATIVE_Z", up_axis="Y")

for material in bpy.data.materials:
    name = material.name.split(".")[0]
    material.use_nodes = True
    bsdf = material.node_tree.nodes.get("Principled BSDF")
    r, g, b = KD[name]
    bsdf.inputs["Base Color"].default_value = (r, g, b, 1.0)
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular"].default_value = 0.0
    if name == "light":
        peak = max(RADIANCE)
        bsdf.inputs["Emission"].default_value = tuple(c / peak for c in RADIANCE) + (1.0,)
        bsdf.inputs["Emission Strength"].default_value = peak
    else:
        bsdf.inputs["Emission"].default_value = (0.0, 0.0, 0.0, 1.0)

# #@camera 0.278 0.273 -0.8  0.278 0.273 0  0 1 0  39.3 (y up), in Blender's
# z-up frame: eye (0.278, 0.8, 0.273) looking down -y.
camera_data = bpy.data.cameras.new("camera")
camera_data.sensor_fit = "VERTICAL"
camera_data.angle_y = math.radians(39.3)
camera = bpy.data.objects.new("camera", camera_data)
camera.location = (0.278, 0.8, 0.273)
camera.rotation_euler = (math.radians(90.0), 0.0, math.radians(180.0))
bpy.context.scene.collection.objects.link(camera)
bpy.context.scene.camera = camera
bpy.context.scene.render.resolution_x = 512
bpy.context.scene.render.resolution_y = 512

OUT.parent.mkdir(parents=True, exist_ok=True)
bpy.ops.export_scene.gltf(
    filepath=str(OUT),
    export_format="GLB",
    export_cameras=True,
    export_yup=True,
    export_apply=True,
)
print(f"wrote {OUT}")
