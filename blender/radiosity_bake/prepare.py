# SPDX-License-Identifier: GPL-3.0-or-later
"""Getting the user's scene ready for a bake, and writing it as glTF.

What is baked: every render-enabled mesh object of the view layer. Each
gets a UV map named ``Lightmap`` (Blender's Lightmap Pack, all the new ones
sharing one atlas) as its second UV map, so the glTF exporter writes it as
``TEXCOORD_1`` and the radiosity bake keeps it; what the bake writes then
lines up with the user's own objects. Objects whose modifiers change their
topology, and meshes drawn by several objects, cannot share one lightmap
with the rest as they are: with the user's consent they are baked from a
copy with the modifiers applied (which the user sees in place of the
original) or from single-user copies, else they are refused by name.

Lights go out as glTF's punctual lights (the exporter converts Blender's
watts at 683 lm/W); area lights, which glTF has no kind for, as emitting
quads or polygons of the same power and size; the World's colour as a
uniform sky (``--sky uniform``) of the same luminance. Everything changed
here is recorded in a :class:`Changes`, undone when the bake fails.
"""

import math
import os

import bpy

#: The UV map the lightmap lives in.
LIGHTMAP_UV = "Lightmap"

#: Custom property marking data the add-on made (its value says what).
OWNED = "radiosity_bake"

#: Blender watts to lumens, as the glTF exporter converts lights.
WATTS_TO_LUMENS = 683.0

#: The radiosity program's efficacy, lumens per radiometric watt
#: (Radiance's), and its luminance weights of R, G, B.
EFFICACY = 179.0
LUMINANCE = (0.265, 0.670, 0.065)

#: Sides of the polygon standing for a disk or ellipse area light.
DISK_SIDES = 32


class BakeError(Exception):
    """A problem the user can fix, said in words they understand."""


class Changes:
    """What preparing a bake did to the user's scene, undone if it fails."""

    def __init__(self):
        self._undo = []

    def add(self, undo):
        """Records a callable that undoes one change."""
        self._undo.append(undo)

    def undo(self):
        """Undoes every change, newest first (a change whose data the user
        has deleted meanwhile is skipped)."""
        while self._undo:
            undo = self._undo.pop()
            try:
                undo()
            except (ReferenceError, RuntimeError, KeyError, ValueError):
                pass

    def keep(self):
        """Keeps the changes (the bake succeeded)."""
        self._undo.clear()


def luminance(rgb):
    """Luminance of a linear RGB colour, with the program's weights."""
    return sum(w * c for w, c in zip(LUMINANCE, rgb))


def render_enabled(obj, view_layer):
    """Whether `obj` takes part in renders of `view_layer`."""
    if obj.name not in view_layer.objects or obj.hide_render:
        return False
    return not any(c.hide_render for c in obj.users_collection)


def mesh_objects(context):
    """The render-enabled mesh objects with faces, by name."""
    layer = context.view_layer
    return sorted(
        (
            o
            for o in layer.objects
            if o.type == "MESH" and render_enabled(o, layer) and len(o.data.polygons) > 0
        ),
        key=lambda o: o.name,
    )


def light_objects(context):
    """The render-enabled lights, by name."""
    layer = context.view_layer
    return sorted(
        (o for o in layer.objects if o.type == "LIGHT" and render_enabled(o, layer)),
        key=lambda o: o.name,
    )


def changes_topology(obj, depsgraph):
    """Whether `obj`'s modifiers give it other vertices or faces than its
    mesh (Subdivision, Mirror, Array, Solidify...): its ``Lightmap`` UV map
    would then be interpolated, mirrored or repeated."""
    if not any(m.show_render for m in obj.modifiers):
        return False
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        before = (len(obj.data.vertices), len(obj.data.polygons), len(obj.data.loops))
        return before != (len(mesh.vertices), len(mesh.polygons), len(mesh.loops))
    finally:
        evaluated.to_mesh_clear()


def applied_copy(obj, depsgraph, changes):
    """A copy of `obj` with its modifiers applied, in its collections, which
    takes its place in renders (the original is hidden, not changed)."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = bpy.data.meshes.new_from_object(
        evaluated, preserve_all_data_layers=True, depsgraph=depsgraph
    )
    copy = obj.copy()
    copy.data = mesh
    copy.modifiers.clear()
    copy.name = obj.name + " (radiosity)"
    copy[OWNED] = "modifiers applied"
    copy["radiosity_source"] = obj.name
    for collection in obj.users_collection:
        collection.objects.link(copy)
    hidden = (obj.hide_render, obj.hide_get())
    obj.hide_render = True
    obj.hide_set(True)

    def undo():
        bpy.data.objects.remove(copy)
        bpy.data.meshes.remove(mesh)
        obj.hide_render, was_hidden = hidden
        obj.hide_set(was_hidden)

    changes.add(undo)
    return copy


def check_objects(context, objects, apply_modifiers, single_user, changes):
    """Refuses, or with consent fixes, the objects that cannot share one
    lightmap as they are; returns the objects to bake."""
    depsgraph = context.evaluated_depsgraph_get()
    topology = [o for o in objects if changes_topology(o, depsgraph)]
    if topology and not apply_modifiers:
        raise BakeError(
            "modifiers change the topology of "
            + ", ".join(repr(o.name) for o in topology)
            + ": tick 'Apply modifiers on copies' to bake them from copies with the modifiers "
            "applied, or apply or remove the modifiers"
        )
    by_mesh = {}
    for o in objects:
        if o not in topology:
            by_mesh.setdefault(o.data.name, []).append(o)
    shared = [group for group in by_mesh.values() if len(group) > 1]
    if shared and not single_user:
        names = "; ".join(", ".join(repr(o.name) for o in group) for group in shared)
        raise BakeError(
            "these objects share one mesh, and each needs its own lightmap texels: "
            + names
            + ": tick 'Make single-user copies', or make them single-user (Object > "
            "Relations > Make Single User)"
        )
    result = []
    for o in objects:
        if o in topology:
            result.append(applied_copy(o, depsgraph, changes))
        else:
            result.append(o)
    for group in shared:
        for o in group[1:]:
            old = o.data
            o.data = old.copy()
            o.data[OWNED] = "single-user copy"

            def undo(o=o, old=old):
                new = o.data
                o.data = old
                bpy.data.meshes.remove(new)

            changes.add(undo)
    return result


def world_area(obj):
    """The surface area of `obj`'s mesh in world units (its transform
    applied)."""
    m = obj.matrix_world
    points = [m @ v.co for v in obj.data.vertices]
    total = 0.0
    for polygon in obj.data.polygons:
        corners = [points[i] for i in polygon.vertices]
        normal = corners[0] * 0.0
        for a, b in zip(corners, corners[1:] + corners[:1]):
            normal = normal + a.cross(b)
        total += 0.5 * normal.length
    return total


def ensure_lightmap_uvs(objects, density, changes):
    """Gives every mesh of `objects` a ``Lightmap`` UV map as its second UV
    map, packing the new ones (with those the add-on made before) into one
    atlas whose margins are about two texels at `density`; returns the
    names of the meshes that got one."""
    from bl_operators.uvcalc_lightmap import lightmap_uvpack

    meshes = {}
    for o in objects:
        meshes.setdefault(o.data.name, (o.data, o))
    new = [m for m, _ in meshes.values() if LIGHTMAP_UV not in m.uv_layers]
    if not new:
        return []
    for m in new:
        made_first = len(m.uv_layers) == 0
        if made_first:
            m.uv_layers.new(name="UVMap")
        m.uv_layers.new(name=LIGHTMAP_UV)
        m[OWNED + "_uv"] = True

        def undo(m=m, made_first=made_first):
            m.uv_layers.remove(m.uv_layers[LIGHTMAP_UV])
            if made_first and "UVMap" in m.uv_layers:
                m.uv_layers.remove(m.uv_layers["UVMap"])
            del m[OWNED + "_uv"]

        changes.add(undo)
    pack = [(m, o) for m, o in meshes.values() if m.get(OWNED + "_uv")]
    # Earlier packings of the add-on's are packed again with the new ones:
    # their old coordinates come back if the bake fails.
    for m, _ in pack:
        if m not in new:
            layer = m.uv_layers[LIGHTMAP_UV]
            saved = [0.0] * (2 * len(layer.uv))
            layer.uv.foreach_get("vector", saved)

            def undo(m=m, saved=saved):
                m.uv_layers[LIGHTMAP_UV].uv.foreach_set("vector", saved)

            changes.add(undo)
    area = sum(world_area(o) for _, o in pack)
    # The pack is about 60% full; margins of two texels of its side.
    side = max(16.0, density * math.sqrt(area / 0.6))
    # Lightmap Pack sizes faces by their area in the mesh's own units:
    # packed on copies in world units, so a scaled object gets the same
    # texels per metre as the rest; the coordinates are copied back (a
    # mesh's copy keeps its corners' order).
    copies = []
    try:
        for m, o in pack:
            copy = m.copy()
            copy.transform(o.matrix_world)
            copy.uv_layers.active = copy.uv_layers[LIGHTMAP_UV]
            copies.append(copy)
        lightmap_uvpack(
            copies,
            PREF_SEL_ONLY=False,
            PREF_NEW_UVLAYER=False,
            PREF_PACK_IN_ONE=True,
            PREF_BOX_DIV=12,
            PREF_MARGIN_DIV=max(16, min(4096, int(side / 2.0))),
        )
        for (m, _), copy in zip(pack, copies):
            uv = [0.0] * (2 * len(copy.loops))
            copy.uv_layers[LIGHTMAP_UV].uv.foreach_get("vector", uv)
            m.uv_layers[LIGHTMAP_UV].uv.foreach_set("vector", uv)
    finally:
        for copy in copies:
            bpy.data.meshes.remove(copy)
    return [m.name for m in new]


class LightmapOrder:
    """Puts each mesh's ``Lightmap`` UV map second for the export (the
    exporter writes UV maps in order, and the bake reads ``TEXCOORD_1``), by
    swapping its name and coordinates with the map there; :meth:`restore`
    swaps them back."""

    def __init__(self, meshes):
        self.swapped = []
        for m in meshes:
            index = m.uv_layers.find(LIGHTMAP_UV)
            if index in (1, -1):
                continue
            if len(m.uv_layers) < 2:
                raise BakeError(f"mesh {m.name!r} has a Lightmap UV map but no other: add one")
            self._swap(m, index, 1)
            self.swapped.append((m, index))

    @staticmethod
    def _swap(m, i, j):
        a, b = m.uv_layers[i], m.uv_layers[j]
        ua = [0.0] * (2 * len(a.uv))
        ub = [0.0] * (2 * len(b.uv))
        a.uv.foreach_get("vector", ua)
        b.uv.foreach_get("vector", ub)
        a.uv.foreach_set("vector", ub)
        b.uv.foreach_set("vector", ua)
        name_a, name_b = a.name, b.name
        a.name = "radiosity swap"
        b.name = name_a
        a.name = name_b

    def restore(self):
        """Swaps the maps back."""
        for m, index in reversed(self.swapped):
            self._swap(m, index, 1)
        self.swapped.clear()


def area_light_polygon(light):
    """The corners (in the light's own frame, on z = 0) of an area light's
    shape, in the order that makes the polygon face -z, the way it shines;
    and the shape's area in that frame."""
    if light.shape in ("SQUARE", "RECTANGLE"):
        sx = light.size
        sy = light.size if light.shape == "SQUARE" else light.size_y
        corners = [(-sx / 2, -sy / 2), (-sx / 2, sy / 2), (sx / 2, sy / 2), (sx / 2, -sy / 2)]
        return corners, sx * sy
    rx = light.size / 2
    ry = rx if light.shape == "DISK" else light.size_y / 2
    n = DISK_SIDES
    # A polygon of the ellipse's area.
    k = math.sqrt(2 * math.pi / (n * math.sin(2 * math.pi / n)))
    corners = [
        (k * rx * math.cos(-2 * math.pi * i / n), k * ry * math.sin(-2 * math.pi * i / n))
        for i in range(n)
    ]
    return corners, math.pi * rx * ry


def area_light_stand_ins(lights, warnings):
    """Emitting polygons standing for the area lights among `lights`, linked
    to the scene for the export (the caller removes them): a light of P
    watts and colour C over A square metres becomes a one-sided polygon
    facing the way it shines whose glTF emission is C at strength
    683 P / (179 pi A), the power the exporter's 683 lm/W gives a point
    light of P watts."""
    made = []
    for obj in lights:
        light = obj.data
        if light.type != "AREA" or light.energy <= 0.0:
            continue
        if getattr(light, "spread", math.pi) < math.pi - 1e-6:
            warnings.append(
                f"area light {obj.name!r}: its spread is left out (baked as 180 degrees)"
            )
        corners, area = area_light_polygon(light)
        sx, sy = obj.matrix_world.to_3x3().col[0].length, obj.matrix_world.to_3x3().col[1].length
        world = area * sx * sy
        if world <= 0.0:
            continue
        mesh = bpy.data.meshes.new(f"{obj.name} (radiosity emitter)")
        mesh.from_pydata([(x, y, 0.0) for x, y in corners], [], [list(range(len(corners)))])
        # Every primitive of a lightmap bake needs TEXCOORD_1: the stand-in
        # takes none of the atlas (a point in its corner, which the packed
        # charts' margins keep clear).
        for name in ("UVMap", LIGHTMAP_UV):
            layer = mesh.uv_layers.new(name=name)
            layer.uv.foreach_set("vector", [0.0] * (2 * len(layer.uv)))
        material = bpy.data.materials.new(f"{obj.name} (radiosity emitter)")
        material.use_nodes = True
        material.use_backface_culling = True
        bsdf = next(n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
        bsdf.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
        bsdf.inputs["Emission Color"].default_value = (*light.color, 1.0)
        bsdf.inputs["Emission Strength"].default_value = (
            WATTS_TO_LUMENS * light.energy / (EFFICACY * math.pi * world)
        )
        mesh.materials.append(material)
        stand_in = bpy.data.objects.new(mesh.name, mesh)
        stand_in.matrix_world = obj.matrix_world.copy()
        bpy.context.scene.collection.objects.link(stand_in)
        made.append(stand_in)
    return made


def remove_stand_ins(made):
    """Removes what :func:`area_light_stand_ins` made."""
    for obj in made:
        mesh = obj.data
        materials = list(mesh.materials)
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(mesh)
        for m in materials:
            if m is not None and m.users == 0:
                bpy.data.materials.remove(m)


def world_sky(scene, warnings):
    """The World's colour as a uniform sky: its horizontal illuminance in
    lux (683 lm/W, as the exporter converts lights), or None (no World, a
    black one, or one made of textures, said in `warnings`)."""
    world = scene.world
    if world is None:
        return None
    colour, strength = tuple(world.color), 1.0
    if world.use_nodes and world.node_tree is not None:
        output = next(
            (n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD" and n.is_active_output),
            None,
        ) or next((n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD"), None)
        link = (
            output.inputs["Surface"].links[0] if output and output.inputs["Surface"].links else None
        )
        if link is None:
            return None
        node = link.from_node
        if node.type != "BACKGROUND" or node.inputs["Color"].links or node.inputs["Strength"].links:
            warnings.append(
                f"World {world.name!r}: only a plain Background colour is baked (as a uniform "
                "sky); its node setup was left out"
            )
            return None
        colour = tuple(node.inputs["Color"].default_value)[:3]
        strength = node.inputs["Strength"].default_value
    lux = math.pi * WATTS_TO_LUMENS * strength * luminance(colour)
    if lux <= 0.0:
        return None
    if max(colour) - min(colour) > 1e-3 * max(colour):
        warnings.append(
            f"World {world.name!r}: baked as a white uniform sky of its luminance (its tint is "
            "left out)"
        )
    return lux


def material_emits(material):
    """Whether a material's nodes emit light (a Principled BSDF's emission
    or an Emission shader, not black)."""
    if material is None or not material.use_nodes or material.node_tree is None:
        return False
    for node in material.node_tree.nodes:
        if node.type == "BSDF_PRINCIPLED":
            colour = node.inputs["Emission Color"]
            strength = node.inputs["Emission Strength"]
            if (colour.links or max(colour.default_value[:3]) > 0) and (
                strength.links or strength.default_value > 0
            ):
                return True
        if node.type == "EMISSION" and (
            node.inputs["Strength"].links or node.inputs["Strength"].default_value > 0
        ):
            return True
    return False


def has_light(objects, lights, sky_lux):
    """Whether anything lights the scene."""
    if sky_lux:
        return True
    if any(o.data.energy > 0 and max(o.data.color) > 0 for o in lights):
        return True
    return any(material_emits(slot.material) for o in objects for slot in o.material_slots)


def default_material(objects, changes):
    """Gives objects without a material the add-on's grey one, so the solve
    and Blender's shading see the same surface (the lightmap is wired into
    materials)."""
    bare = [o for o in objects if not any(s.material for s in o.material_slots)]
    if not bare:
        return
    material = bpy.data.materials.get("Radiosity Default")
    if material is None:
        material = bpy.data.materials.new("Radiosity Default")
        material.use_nodes = True
        material[OWNED] = "default material"
    for o in bare:
        had_slots = len(o.material_slots)
        if had_slots == 0:
            o.data.materials.append(material)
        else:
            o.material_slots[0].material = material

        def undo(o=o, had_slots=had_slots):
            if had_slots == 0:
                o.data.materials.pop()
            else:
                o.material_slots[0].material = None

        changes.add(undo)


def export(context, path, objects, lights):
    """Writes `objects`, `lights` (area lights as stand-ins) and the scene's
    camera to the binary glTF `path`, as they render (modifiers applied)."""
    warnings = []
    stand_ins = area_light_stand_ins(lights, warnings)
    selected = list(context.selected_objects)
    active = context.view_layer.objects.active
    order = LightmapOrder({o.data for o in objects})
    try:
        for o in selected:
            o.select_set(False)
        chosen = objects + [o for o in lights if o.data.type != "AREA"] + stand_ins
        if (
            context.scene.camera is not None
            and context.scene.camera.name in context.view_layer.objects
        ):
            chosen.append(context.scene.camera)
        for o in chosen:
            o.select_set(True)
        result = bpy.ops.export_scene.gltf(
            filepath=path,
            export_format="GLB",
            use_selection=True,
            export_apply=True,
            export_lights=True,
            export_cameras=True,
            export_texcoords=True,
            export_normals=True,
            export_materials="EXPORT",
            export_yup=True,
            export_animations=False,
            export_skins=False,
            export_morph=False,
            export_extras=False,
            export_import_convert_lighting_mode="SPEC",
        )
        if "FINISHED" not in result or not os.path.isfile(path):
            raise BakeError(f"the glTF export to {path} failed")
    finally:
        order.restore()
        remove_stand_ins(stand_ins)
        for o in context.view_layer.objects:
            o.select_set(False)
        for o in selected:
            if o.name in context.view_layer.objects:
                o.select_set(True)
        context.view_layer.objects.active = active
    return warnings
