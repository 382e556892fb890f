"""Export a room lit by Blender lights as glTF, the way a Blender user would
hand such a scene to radiosity: tests/data/blender-lights.glb.

A 5 x 3 x 4 m room (Blender's z up) with a window in one wall, a table, a
point lamp under the ceiling, a spot over the table and the sun shining in
through the window; materials are Principled BSDFs with no emission, so the
three lights are all that lights it. Exported with Blender's bundled glTF
exporter (io_scene_gltf2), +Y up, punctual lights included. Its lighting
mode is the exporter's default ("Standard": physical units), so a point
light of P W is written as P x 683 / (4 pi) candela and the sun's strength
S W/m^2 as S lux... as the exporter documents; radiosity reads what is
written.

Run (from the repository root) with Blender as a Python module:
  python3 -m venv /tmp/bpy-venv && /tmp/bpy-venv/bin/pip install bpy
  /tmp/bpy-venv/bin/python tools/blender_lights.py
The committed .glb is what crates/radiosity/tests/lights.rs reads; CI needs
no Blender.
"""

import math
from pathlib import Path

import bpy

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests" / "data" / "blender-lights.glb"

bpy.ops.wm.read_factory_settings(use_empty=True)


def material(name, colour):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = colour + (1.0,)
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = 1.0
    return m


WHITE = material("white", (0.7, 0.7, 0.7))
FLOOR = material("floor", (0.45, 0.35, 0.25))
TABLE = material("table", (0.5, 0.5, 0.55))


def quad(name, corners, mat):
    """A one-sided quad, counter-clockwise seen from its front."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


# Blender coordinates: x east, y north, z up. The room spans x 0..5,
# y 0..4, z 0..3; faces point into the room.
W, D, H = 5.0, 4.0, 3.0
quad("floor", [(0, 0, 0), (W, 0, 0), (W, D, 0), (0, D, 0)], FLOOR)
quad("ceiling", [(0, 0, H), (0, D, H), (W, D, H), (W, 0, H)], WHITE)
quad("west", [(0, 0, 0), (0, D, 0), (0, D, H), (0, 0, H)], WHITE)
quad("east", [(W, 0, 0), (W, 0, H), (W, D, H), (W, D, 0)], WHITE)
quad("north", [(0, D, 0), (W, D, 0), (W, D, H), (0, D, H)], WHITE)
# The south wall (y = 0, facing +y) around a window x 1.5..3.5, z 0.9..2.1.
for name, (x0, z0, x1, z1) in {
    "south low": (0, 0, W, 0.9),
    "south high": (0, 2.1, W, H),
    "south west": (0, 0.9, 1.5, 2.1),
    "south east": (3.5, 0.9, W, 2.1),
}.items():
    quad(name, [(x0, 0, z0), (x0, 0, z1), (x1, 0, z1), (x1, 0, z0)], WHITE)
# A table top facing up.
quad("table", [(2.8, 1.8, 0.75), (4.0, 1.8, 0.75), (4.0, 2.8, 0.75), (2.8, 2.8, 0.75)], TABLE)


def light(name, kind, energy, location, rotation=(0.0, 0.0, 0.0)):
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    return data


# A 60 W point lamp under the ceiling; a 200 W spot pointing straight down
# at the table (Blender lights shine along their local -z); the sun from the
# south-east, 35 degrees up, strength 5 (W/m^2, Blender's sun unit).
light("lamp", "POINT", 60.0, (1.5, 2.5, 2.7))
spot = light("spot", "SPOT", 200.0, (3.4, 2.3, 2.9))
spot.spot_size = math.radians(50.0)
spot.spot_blend = 0.3
light("sun", "SUN", 5.0, (2.5, -3.0, 5.0),
      (math.radians(55.0), 0.0, math.radians(-20.0)))

OUT.parent.mkdir(parents=True, exist_ok=True)
bpy.ops.export_scene.gltf(filepath=str(OUT), export_format="GLB", export_yup=True,
                          export_lights=True)
print("wrote", OUT)
