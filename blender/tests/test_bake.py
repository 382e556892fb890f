# SPDX-License-Identifier: GPL-3.0-or-later
"""The Blender add-on, end to end, with Blender as a Python module (``bpy``).

A room with a window, a point lamp under the ceiling, the sun shining in
through the window, a dim World and a cube on the floor are built here and
baked with ``bpy.ops.radiosity.bake()``. Checked:

* every mesh has a ``Lightmap`` UV map, second; the lightmap is packed and
  wired into every material through the add-on's node group;
* the lightmap's texels against the radiosity program's ``--sensors`` at
  the same surface points (the texel centres mapped back to the surfaces
  through the ``Lightmap`` UVs), on the same exported file: L1 within 3%;
* a second bake replaces the add-on's image, group and nodes (none doubled);
* Cycles (CPU, Standard view transform) renders the lit look within 2
  levels (8-bit, mean absolute difference) of the program's own picture
  from the same camera;
* errors name the problem and leave the scene as it was: no program, no
  light, meshes shared without consent, a solve the program refuses.

Run: ``RADIOSITY_BIN=target/release/radiosity python blender/tests/test_bake.py``
with ``bpy`` installed (``.ci/blender-tests`` does it).
"""

import csv
import json
import math
import os
import random
import subprocess
import sys
import tempfile
import time
import unittest
import zipfile
from pathlib import Path

import bpy
from mathutils import Vector

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "blender"))

import radiosity_bake
from radiosity_bake import apply as bake_apply
from radiosity_bake import job as bake_job
from radiosity_bake.prepare import LIGHTMAP_UV, BakeError

BINARY = os.environ.get("RADIOSITY_BIN") or str(ROOT / "target" / "release" / "radiosity")
WIDTH, HEIGHT = 120, 90


def material(name, colour):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes.get("Principled BSDF")
    bsdf.inputs["Base Color"].default_value = colour + (1.0,)
    bsdf.inputs["Roughness"].default_value = 1.0
    # One-sided: the outsides of the walls receive nothing.
    m.use_backface_culling = True
    return m


def build_scene():
    """The room (Blender's z up, x 0..4, y 0..4, z 0..3, faces inward), a
    window in the south wall, a cube, a point lamp, the sun, a dim World."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    white = material("walls", (0.7, 0.7, 0.7))
    floor = material("floor", (0.5, 0.4, 0.3))
    red = material("cube", (0.7, 0.2, 0.15))
    w, d, h = 4.0, 4.0, 3.0
    verts, faces, mats = [], [], []

    def quad(corners, m):
        base = len(verts)
        verts.extend(corners)
        faces.append([base, base + 1, base + 2, base + 3])
        mats.append(m)

    quad([(0, 0, 0), (w, 0, 0), (w, d, 0), (0, d, 0)], 1)
    quad([(0, 0, h), (0, d, h), (w, d, h), (w, 0, h)], 0)
    quad([(0, 0, 0), (0, d, 0), (0, d, h), (0, 0, h)], 0)
    quad([(w, 0, 0), (w, 0, h), (w, d, h), (w, d, 0)], 0)
    quad([(0, d, 0), (w, d, 0), (w, d, h), (0, d, h)], 0)
    for x0, z0, x1, z1 in ((0, 0, w, 0.9), (0, 2.1, w, h), (0, 0.9, 1.4, 2.1), (2.6, 0.9, w, 2.1)):
        quad([(x0, 0, z0), (x0, 0, z1), (x1, 0, z1), (x1, 0, z0)], 0)
    mesh = bpy.data.meshes.new("room")
    mesh.from_pydata(verts, [], faces)
    mesh.materials.append(white)
    mesh.materials.append(floor)
    for polygon, m in zip(mesh.polygons, mats):
        polygon.material_index = m
    room = bpy.data.objects.new("room", mesh)
    scene.collection.objects.link(room)

    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(2.6, 2.4, 0.4))
    cube = bpy.context.active_object
    cube.name = "cube"
    cube.data.materials.append(red)

    lamp = bpy.data.lights.new("lamp", "POINT")
    lamp.energy = 60.0
    lamp_obj = bpy.data.objects.new("lamp", lamp)
    lamp_obj.location = (1.0, 2.8, 2.7)
    scene.collection.objects.link(lamp_obj)
    sun = bpy.data.lights.new("sun", "SUN")
    sun.energy = 4.0
    sun_obj = bpy.data.objects.new("sun", sun)
    # Shining north and down through the south window (-z is its direction).
    sun_obj.rotation_euler = (math.radians(50.0), 0.0, math.radians(10.0))
    sun_obj.location = (2.0, -3.0, 4.0)
    scene.collection.objects.link(sun_obj)

    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.04, 0.04, 0.04, 1.0)
    scene.world = world

    camera = bpy.data.cameras.new("camera")
    camera.lens = 24.0
    camera_obj = bpy.data.objects.new("camera", camera)
    camera_obj.location = (0.4, 0.6, 1.7)
    direction = Vector((3.6, 3.4, 0.3)) - camera_obj.location
    camera_obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(camera_obj)
    scene.camera = camera_obj
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    return scene


def owned_nodes(material):
    return [n for n in material.node_tree.nodes if n.get("radiosity_bake") == "lightmap node"]


def blender_to_gltf(v):
    return (v[0], v[2], -v[1])


class BakeTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        os.environ["RADIOSITY_BIN"] = BINARY
        try:
            radiosity_bake.register()
        except ValueError:
            pass  # registered by an earlier test class
        cls.folder = tempfile.mkdtemp(prefix="radiosity-blender-test-")
        cls.scene = build_scene()
        settings = cls.scene.radiosity_bake
        settings.work_folder = cls.folder
        settings.device = "cpu"
        result = bpy.ops.radiosity.bake()
        assert result == {"FINISHED"}, result
        cls.first_pixels = list(bpy.data.images[bake_apply.IMAGE_NAME].pixels)

    def meshes(self):
        return [o for o in self.scene.objects if o.type == "MESH"]

    def test_lightmap_uv_maps_are_second(self):
        for o in self.meshes():
            self.assertEqual(o.data.uv_layers.find(LIGHTMAP_UV), 1, o.name)

    def test_the_lightmap_is_packed_and_wired(self):
        image = bpy.data.images[bake_apply.IMAGE_NAME]
        self.assertIsNotNone(image.packed_file)
        self.assertGreater(image.size[0], 16)
        group = bpy.data.node_groups[bake_apply.GROUP_NAME]
        textures = [n for n in group.nodes if n.type == "TEX_IMAGE"]
        self.assertEqual([t.image for t in textures], [image])
        uv = [n for n in group.nodes if n.type == "UVMAP"]
        self.assertEqual([n.uv_map for n in uv], [LIGHTMAP_UV])
        for o in self.meshes():
            for slot in o.material_slots:
                nodes = owned_nodes(slot.material)
                self.assertEqual(len(nodes), 1, slot.material.name)
                output = slot.material.node_tree.get_output_node("ALL")
                link = output.inputs["Surface"].links[0]
                self.assertEqual(link.from_node, nodes[0])
                self.assertEqual(nodes[0].node_tree, group)

    def texel_points(self, count):
        """Texel centres strictly inside the Lightmap UV triangles, away
        from the edges, mapped to world points: (texel, point, normal)."""
        image = bpy.data.images[bake_apply.IMAGE_NAME]
        width, height = image.size
        rng = random.Random(7)
        candidates = []
        for o in self.meshes():
            mesh = o.data
            mesh.calc_loop_triangles()
            uv = mesh.uv_layers[LIGHTMAP_UV].uv
            normal_matrix = o.matrix_world.to_3x3().inverted().transposed()
            for tri in mesh.loop_triangles:
                corners_uv = [Vector(uv[i].vector) for i in tri.loops]
                corners = [o.matrix_world @ mesh.vertices[i].co for i in tri.vertices]
                normal = (normal_matrix @ tri.normal).normalized()
                candidates.append((corners_uv, corners, normal))
        points = []
        attempts = 0
        while len(points) < count and attempts < 100 * count:
            attempts += 1
            corners_uv, corners, normal = rng.choice(candidates)
            a, b, c = corners_uv
            u, v = rng.random(), rng.random()
            if u + v > 1:
                u, v = 1 - u, 1 - v
            p = a + (b - a) * u + (c - a) * v
            i, j = int(p.x * width), int(p.y * height)
            centre = Vector(((i + 0.5) / width, (j + 0.5) / height))
            # Barycentric coordinates of the texel centre.
            m = (b - a).x * (c - a).y - (b - a).y * (c - a).x
            if abs(m) < 1e-12:
                continue
            q = centre - a
            s = (q.x * (c - a).y - q.y * (c - a).x) / m
            t = ((b - a).x * q.y - (b - a).y * q.x) / m
            # Away from the triangle's edges by about two texels.
            margin = 2.5 / (abs(m) ** 0.5 * max(width, height))
            if min(s, t, 1 - s - t) < margin:
                continue
            world = corners[0] + (corners[1] - corners[0]) * s + (corners[2] - corners[0]) * t
            points.append(((i, j), world, normal))
        return points

    def test_texels_match_sensors_at_the_same_points(self):
        image = bpy.data.images[bake_apply.IMAGE_NAME]
        width, _ = image.size
        pixels = list(image.pixels)
        points = self.texel_points(150)
        self.assertGreater(len(points), 100)
        sensors = os.path.join(self.folder, "texels.txt")
        with open(sensors, "w") as f:
            for _, p, n in points:
                f.write("%r %r %r %r %r %r\n" % (blender_to_gltf(p) + blender_to_gltf(n)))
        out = os.path.join(self.folder, "texels.csv")
        # The same solve as the bake: its own command on its exported file.
        settings = self.scene.radiosity_bake
        sky = bake_job.prepare.world_sky(self.scene, [])
        command = bake_job.settings_command(
            BINARY,
            settings,
            self.scene,
            os.path.join(self.folder, "scene.glb"),
            os.path.join(self.folder, "sensors"),
            sky,
        )
        os.makedirs(os.path.join(self.folder, "sensors"), exist_ok=True)
        subprocess.run(command + ["--sensors", sensors, "--sensors-out", out, "-q"], check=True)
        record = bake_apply.glb_extras(os.path.join(self.folder, "baked.glb"))
        exposure = record["picture_exposure"]
        ambient = record["ambient"]
        with open(out) as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), len(points))
        errors, total = 0.0, 0.0
        for ((i, j), _, _), row in zip(points, rows):
            e = [float(row[k]) for k in ("er", "eg", "eb")]
            b = [float(row[k]) for k in ("br", "bg", "bb")]
            # The lit lightmap is what the picture shows: (B + rho x
            # ambient) x the picture's exposure.
            expected = [
                (bc + (bc / ec if ec > 0 else 0.0) * a) * exposure
                for bc, ec, a in zip(b, e, ambient)
            ]
            k = 4 * (j * width + i)
            got = pixels[k : k + 3]
            errors += sum(abs(g - x) for g, x in zip(got, expected))
            total += sum(expected)
        l1 = errors / total
        print(f"lightmap texels against sensors: L1 {100 * l1:.2f}% over {len(points)} points")
        self.assertLess(l1, 0.03)

    def test_z_rebake_replaces_its_own_nodes_and_image(self):
        images = len(bpy.data.images)
        groups = len(bpy.data.node_groups)
        self.assertEqual(bpy.ops.radiosity.bake(), {"FINISHED"})
        self.assertEqual(len(bpy.data.images), images)
        self.assertEqual(len(bpy.data.node_groups), groups)
        self.assertIn(bake_apply.IMAGE_NAME, bpy.data.images)
        # The same solve of the same materials (not the first bake's light
        # taken for emission): the same lightmap.
        pixels = list(bpy.data.images[bake_apply.IMAGE_NAME].pixels)
        self.assertEqual(len(pixels), len(self.first_pixels))
        worst = max(abs(a - b) for a, b in zip(pixels, self.first_pixels))
        self.assertLess(worst, 1e-6)
        for o in self.meshes():
            self.assertEqual(len(o.data.uv_layers), 2, o.name)
            for slot in o.material_slots:
                self.assertEqual(len(owned_nodes(slot.material)), 1, slot.material.name)

    def test_zy_a_lightmap_map_third_in_the_list_is_used(self):
        # The room's Lightmap map moved third (behind a copy named Extra):
        # the export puts it second for the time of the export, and the
        # bake reads the same coordinates, so the lightmap is the same.
        mesh = self.scene.objects["room"].data
        lightmap = mesh.uv_layers[LIGHTMAP_UV]
        uv = [0.0] * (2 * len(lightmap.uv))
        lightmap.uv.foreach_get("vector", uv)
        third = mesh.uv_layers.new(name="third")
        third.uv.foreach_set("vector", uv)
        lightmap.name = "Extra"
        third.name = LIGHTMAP_UV
        names = [layer.name for layer in mesh.uv_layers]
        self.assertEqual(names, ["UVMap", "Extra", LIGHTMAP_UV])
        self.assertEqual(bpy.ops.radiosity.bake(), {"FINISHED"})
        self.assertEqual([layer.name for layer in mesh.uv_layers], names)
        after = [0.0] * len(uv)
        mesh.uv_layers[LIGHTMAP_UV].uv.foreach_get("vector", after)
        self.assertEqual(after, uv)
        pixels = list(bpy.data.images[bake_apply.IMAGE_NAME].pixels)
        worst = max(abs(a - b) for a, b in zip(pixels, self.first_pixels))
        self.assertLess(worst, 1e-6)

    def test_zz_clear_restores_the_materials(self):
        self.assertEqual(bpy.ops.radiosity.clear(), {"FINISHED"})
        self.assertNotIn(bake_apply.IMAGE_NAME, bpy.data.images)
        self.assertNotIn(bake_apply.GROUP_NAME, bpy.data.node_groups)
        for o in self.meshes():
            self.assertIn(LIGHTMAP_UV, o.data.uv_layers, o.name)
            for slot in o.material_slots:
                tree = slot.material.node_tree
                self.assertEqual(owned_nodes(slot.material), [])
                link = tree.get_output_node("ALL").inputs["Surface"].links[0]
                self.assertEqual(link.from_node.type, "BSDF_PRINCIPLED", slot.material.name)

    def test_cycles_renders_the_lit_look_as_our_picture(self):
        self.assertLessEqual(cycles_against_picture(self.scene, self.folder), 2.0)

    def test_every_light_reached_the_surfaces(self):
        with open(os.path.join(self.folder, "stats.json")) as f:
            lights = json.load(f)["lights"]
        self.assertEqual(sorted(l["type"] for l in lights), ["point", "sky", "sun"])
        for light in lights:
            self.assertGreater(light["lumens"], 0.0, light["name"])
        point = next(l for l in lights if l["type"] == "point")
        # The exporter's 683 lm per Blender watt.
        self.assertAlmostEqual(point["lumens"], 60.0 * 683.0, delta=1e-6 * 60.0 * 683.0)


def cycles_against_picture(scene, folder):
    """Renders `scene` with Cycles on the CPU (Standard view transform) and
    returns the mean absolute difference, in 8-bit levels, from the
    program's own picture (picture.png in `folder`) of the same camera."""
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.dither_intensity = 0.0
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_depth = "8"
    scene.render.image_settings.color_mode = "RGB"
    for o in scene.objects:
        if o.type == "LIGHT":
            o.visible_camera = False
    path = os.path.join(folder, "cycles.png")
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    ours = bpy.data.images.load(os.path.join(folder, "picture.png"), check_existing=False)
    theirs = bpy.data.images.load(path, check_existing=False)
    assert tuple(ours.size) == (WIDTH, HEIGHT), tuple(ours.size)
    assert tuple(theirs.size) == (WIDTH, HEIGHT), tuple(theirs.size)
    a, b = list(ours.pixels), list(theirs.pixels)
    bpy.data.images.remove(ours)
    bpy.data.images.remove(theirs)
    # A picture worth comparing: lit, not clipped white.
    level = 255.0 * sum(x for k, x in enumerate(a) if k % 4 != 3) / (0.75 * len(a))
    assert 40.0 < level < 215.0, level
    diff = [abs(x - y) * 255.0 for k, (x, y) in enumerate(zip(a, b)) if k % 4 != 3]
    mean = sum(diff) / len(diff)
    print(f"Cycles against our picture: mean absolute difference {mean:.2f} levels")
    return mean


class ErrorTest(unittest.TestCase):
    """Errors name the problem and leave the scene unchanged."""

    def setUp(self):
        try:
            radiosity_bake.register()
        except ValueError:
            pass
        os.environ["RADIOSITY_BIN"] = BINARY
        self.scene = build_scene()
        self.scene.radiosity_bake.device = "cpu"

    def bake_error(self):
        with self.assertRaises(BakeError) as caught:
            bake_job.Job(bpy.context).run(report=lambda _: None)
        # Nothing was left behind.
        for o in self.scene.objects:
            if o.type == "MESH":
                self.assertNotIn(LIGHTMAP_UV, o.data.uv_layers, o.name)
        self.assertNotIn(bake_apply.IMAGE_NAME, bpy.data.images)
        # The operator reports the same error (which a script sees raised).
        with self.assertRaises(RuntimeError) as reported:
            bpy.ops.radiosity.bake()
        self.assertIn(str(caught.exception), str(reported.exception))
        return str(caught.exception)

    def test_no_program(self):
        os.environ["RADIOSITY_BIN"] = os.path.join(tempfile.gettempdir(), "no-such-radiosity")
        path = os.environ.get("PATH", "")
        os.environ["PATH"] = ""
        try:
            message = self.bake_error()
        finally:
            os.environ["PATH"] = path
        self.assertIn("radiosity program was not found", message)
        self.assertIn("RADIOSITY_BIN", message)

    def test_no_light(self):
        for o in list(self.scene.objects):
            if o.type == "LIGHT":
                bpy.data.objects.remove(o)
        self.scene.world = None
        self.assertIn("nothing lights the scene", self.bake_error())

    def test_shared_meshes_need_consent(self):
        cube = self.scene.objects["cube"]
        twin = cube.copy()
        twin.name = "twin"
        twin.location.x -= 1.5
        self.scene.collection.objects.link(twin)
        message = self.bake_error()
        self.assertIn("'cube', 'twin'", message)
        self.assertIn("single-user", message)

    def test_a_refused_solve_names_the_programs_message(self):
        settings = self.scene.radiosity_bake
        settings.preset = "wallace89"
        settings.device = "gpu"
        message = self.bake_error()
        self.assertIn("the solve failed", message)
        self.assertIn("--device gpu runs the default method", message)


def register():
    try:
        radiosity_bake.register()
    except ValueError:
        pass  # registered already


class ConsentTest(unittest.TestCase):
    """Modifiers that change topology and shared meshes, with consent; the
    kept-shading look rendered by Cycles."""

    @classmethod
    def setUpClass(cls):
        register()
        os.environ["RADIOSITY_BIN"] = BINARY
        cls.scene = build_scene()
        cube = cls.scene.objects["cube"]
        twin = cube.copy()
        twin.name = "twin"
        twin.location = (1.0, 3.2, 0.4)
        cls.scene.collection.objects.link(twin)
        bpy.ops.mesh.primitive_cube_add(size=0.4, location=(3.2, 1.0, 0.2))
        mirrored = bpy.context.active_object
        mirrored.name = "mirrored"
        mirrored.data.materials.append(bpy.data.materials["cube"])
        modifier = mirrored.modifiers.new("mirror", "MIRROR")
        modifier.use_axis = (True, False, False)
        modifier.mirror_object = cube
        # A cube scaled twice and one of its size: the same texels per
        # metre (Lightmap Pack sizes faces in powers of two, so the same
        # world size gives the same boxes, and the scale ignored a quarter).
        bpy.ops.mesh.primitive_cube_add(size=0.4, location=(0.5, 2.0, 0.4))
        scaled = bpy.context.active_object
        scaled.name = "scaled"
        scaled.scale = (2.0, 2.0, 2.0)
        bpy.ops.mesh.primitive_cube_add(size=0.8, location=(3.5, 3.5, 0.4))
        bpy.context.active_object.name = "reference"
        cls.folder = tempfile.mkdtemp(prefix="radiosity-blender-consent-")
        settings = cls.scene.radiosity_bake
        settings.work_folder = cls.folder
        settings.device = "cpu"
        settings.apply_modifiers = True
        settings.single_user = True
        settings.look = "SHADING"
        assert bpy.ops.radiosity.bake() == {"FINISHED"}

    def test_modifiers_were_applied_on_a_visible_copy(self):
        original = self.scene.objects["mirrored"]
        copy = self.scene.objects["mirrored (radiosity)"]
        self.assertTrue(original.hide_render)
        self.assertFalse(copy.hide_render)
        self.assertEqual(len(copy.modifiers), 0)
        self.assertEqual(len(copy.data.polygons), 2 * len(original.data.polygons))
        self.assertEqual(copy.data.uv_layers.find(LIGHTMAP_UV), 1)
        self.assertNotIn(LIGHTMAP_UV, original.data.uv_layers)

    def test_shared_meshes_got_copies(self):
        cube, twin = self.scene.objects["cube"], self.scene.objects["twin"]
        self.assertNotEqual(cube.data, twin.data)
        for o in (cube, twin):
            self.assertEqual(o.data.uv_layers.find(LIGHTMAP_UV), 1, o.name)

    def test_texels_per_metre_do_not_depend_on_an_objects_scale(self):
        def uv_per_world_area(o):
            mesh = o.data
            mesh.calc_loop_triangles()
            uv = mesh.uv_layers[LIGHTMAP_UV].uv
            uv_area = world = 0.0
            for tri in mesh.loop_triangles:
                a, b, c = (Vector(uv[i].vector) for i in tri.loops)
                uv_area += abs((b - a).x * (c - a).y - (b - a).y * (c - a).x) / 2
                p, q, r = (o.matrix_world @ mesh.vertices[i].co for i in tri.vertices)
                world += (q - p).cross(r - p).length / 2
            return uv_area / world

        ratio = uv_per_world_area(self.scene.objects["scaled"]) / uv_per_world_area(
            self.scene.objects["reference"]
        )
        self.assertAlmostEqual(ratio, 1.0, delta=0.1)

    def test_cycles_renders_kept_shading_as_our_picture(self):
        self.assertLessEqual(cycles_against_picture(self.scene, self.folder), 2.0)


class StopTest(unittest.TestCase):
    """Stopping (Esc once: the stop file) bakes the light reached;
    abandoning (Esc twice) leaves the scene as it was."""

    def setUp(self):
        register()
        os.environ["RADIOSITY_BIN"] = BINARY
        self.scene = build_scene()
        settings = self.scene.radiosity_bake
        settings.device = "cpu"
        # A stopping rule no solve reaches: only the stop ends it.
        settings.extra_arguments = "--converge 1e-12"

    def started(self):
        bake = bake_job.Job(bpy.context)
        bake.start()
        while bake.solve.progress is None:
            self.assertFalse(bake.poll(), "the program ended before its first shot")
            time.sleep(0.05)
        return bake

    def test_stop_bakes_the_light_reached(self):
        bake = self.started()
        bake.request_stop()
        while not bake.poll():
            time.sleep(0.05)
        result = bake.finish()
        self.assertEqual(result["stop_reason"], "stopped")
        self.assertGreater(result["shots"], 0)
        self.assertIn(bake_apply.IMAGE_NAME, bpy.data.images)
        for o in self.scene.objects:
            if o.type == "MESH":
                self.assertEqual(o.data.uv_layers.find(LIGHTMAP_UV), 1, o.name)

    def test_abandon_leaves_the_scene_as_it_was(self):
        bake = self.started()
        bake.abandon()
        self.assertIsNotNone(bake.solve.process.poll())
        self.assertNotIn(bake_apply.IMAGE_NAME, bpy.data.images)
        for o in self.scene.objects:
            if o.type == "MESH":
                self.assertNotIn(LIGHTMAP_UV, o.data.uv_layers, o.name)
                for slot in o.material_slots:
                    self.assertEqual(owned_nodes(slot.material), [])


class AreaLightTest(unittest.TestCase):
    """An area light becomes an emitter of the same power: under a square
    light of P watts, side a, at height h, a floor point's irradiance is
    the exitance 683 P / (179 a^2) times the form factor to a parallel
    square centred above it."""

    def test_irradiance_below_a_square_area_light(self):
        register()
        os.environ["RADIOSITY_BIN"] = BINARY
        bpy.ops.wm.read_factory_settings(use_empty=True)
        scene = bpy.context.scene
        mesh = bpy.data.meshes.new("floor")
        mesh.from_pydata([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)], [], [(0, 1, 2, 3)])
        mesh.materials.append(material("floor", (0.5, 0.5, 0.5)))
        scene.collection.objects.link(bpy.data.objects.new("floor", mesh))
        power, side, height = 100.0, 0.5, 2.0
        light = bpy.data.lights.new("panel", "AREA")
        light.shape = "SQUARE"
        light.size = side
        light.energy = power
        panel = bpy.data.objects.new("panel", light)
        panel.location = (0.0, 0.0, height)
        scene.collection.objects.link(panel)
        folder = tempfile.mkdtemp(prefix="radiosity-blender-area-")
        points = os.path.join(folder, "points.txt")
        with open(points, "w") as f:
            f.write("0 0 0 0 1 0\n0.7 0 -0.4 0 1 0\n")
        settings = scene.radiosity_bake
        settings.device = "cpu"
        settings.world_as_sky = False
        settings.work_folder = folder
        settings.extra_arguments = f"--sensors {points} --sensors-out {folder}/points.csv"
        self.assertEqual(bpy.ops.radiosity.bake(), {"FINISHED"})
        # The stand-in was removed after the export.
        self.assertEqual([o.name for o in scene.objects if o.type == "MESH"], ["floor"])
        with open(os.path.join(folder, "points.csv")) as f:
            rows = list(csv.DictReader(f))

        def corner(x, y):
            # dA below a corner of an x by y rectangle at unit height.
            a, b = math.sqrt(1 + x * x), math.sqrt(1 + y * y)
            return (x / a * math.atan(y / a) + y / b * math.atan(x / b)) / (2 * math.pi)

        def factor(px, py):
            # The square's corners relative to the point, at height h.
            x0, x1 = (-side / 2 - px) / height, (side / 2 - px) / height
            y0, y1 = (-side / 2 - py) / height, (side / 2 - py) / height

            def signed(x, y):
                # The rectangle from below the point to (x, y), signed.
                return math.copysign(1.0, x) * math.copysign(1.0, y) * corner(abs(x), abs(y))

            return signed(x1, y1) - signed(x0, y1) - signed(x1, y0) + signed(x0, y0)

        exitance = 683.0 * power / (179.0 * side * side)
        # Blender (x, y) of each point: glTF (x, -z).
        for row, (px, py) in zip(rows, ((0.0, 0.0), (0.7, 0.4))):
            expected = exitance * factor(px, py)
            got = float(row["er"])
            print(f"irradiance below the area light: {got:.5f} against {expected:.5f}")
            self.assertAlmostEqual(got, expected, delta=0.01 * expected)


INSTALLED = """
import os, sys, bpy
zip_path, binary, folder = sys.argv[1:4]
assert bpy.ops.extensions.package_install_files(
    filepath=zip_path, repo="user_default", enable_on_install=True
) == {"FINISHED"}
addon = bpy.context.preferences.addons["bl_ext.user_default.radiosity_bake"]
addon.preferences.binary = binary  # no RADIOSITY_BIN, no PATH: the preferences
scene = bpy.context.scene
for o in list(scene.objects):
    bpy.data.objects.remove(o)
scene.world = None
mesh = bpy.data.meshes.new("floor")
mesh.from_pydata([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [], [(0, 1, 2, 3)])
scene.collection.objects.link(bpy.data.objects.new("floor", mesh))
sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
scene.collection.objects.link(sun)
scene.radiosity_bake.device = "cpu"
scene.radiosity_bake.work_folder = folder
assert bpy.ops.radiosity.bake() == {"FINISHED"}
assert bpy.data.images["Radiosity Lightmap"].packed_file is not None
print("installed extension baked", flush=True)
os._exit(0)  # see exit_now
"""


class InstallTest(unittest.TestCase):
    """The README's install: the zip it says how to make, installed by
    Blender's own extension installer into a fresh user folder, the program
    named in the add-on's preferences."""

    def test_the_zip_installs_and_bakes(self):
        home = tempfile.mkdtemp(prefix="radiosity-blender-home-")
        archive = os.path.join(home, "radiosity_bake.zip")
        # cd blender && zip -r ../radiosity_bake.zip radiosity_bake -x '*/__pycache__/*'
        with zipfile.ZipFile(archive, "w") as z:
            for path in sorted((ROOT / "blender" / "radiosity_bake").rglob("*")):
                if path.is_file() and "__pycache__" not in path.parts:
                    z.write(path, path.relative_to(ROOT / "blender"))
        env = dict(os.environ, HOME=home, BLENDER_USER_RESOURCES=os.path.join(home, "blender"))
        env.pop("RADIOSITY_BIN", None)
        env["PATH"] = os.path.dirname(sys.executable)
        folder = os.path.join(home, "bake")
        out = subprocess.run(
            [sys.executable, "-c", INSTALLED, archive, BINARY, folder],
            check=False,
            env=env,
            capture_output=True,
            text=True,
            cwd=home,
        )
        self.assertEqual(out.returncode, 0, out.stdout[-3000:] + out.stderr[-3000:])
        self.assertIn("installed extension baked", out.stdout)


def exit_now(code):
    """Ends the process without Python's and Blender's teardown: bpy
    4.2.23 as a module crashes at exit (SIGSEGV) once a glTF export has
    run, even a plain ``export_scene.gltf`` with no add-on of ours, which
    would turn a passing run into a failure."""
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    outcome = unittest.main(verbosity=2, exit=False).result
    exit_now(0 if outcome.wasSuccessful() else 1)
