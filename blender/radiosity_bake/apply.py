# SPDX-License-Identifier: GPL-3.0-or-later
"""Bringing the baked light back onto the user's objects.

The bake's linear lightmap (the EXR the radiosity program writes beside its
glTF) is packed into the .blend as the image ``Radiosity Lightmap`` and read
through each object's ``Lightmap`` UV map by a node group the add-on owns,
``Radiosity Lightmap``, which each baked material's output takes as its
surface:

* **lit** look: the group emits the lightmap as it is (the radiance our
  picture shows, at its exposure): every renderer shows the solved light
  and nothing else, as a lightmapped game engine does;
* **kept shading**: the lightmap holds irradiance over pi, and the group
  emits it times the material's own base colour (its texture too), scaled
  back to the picture's radiance: the light of the solve, the detail of the
  textures.

The material's previous surface is remembered on the group node, so a new
bake replaces the add-on's nodes and image, and :func:`clear` puts every
material back as it was. Everything that can fail (reading the image and
the bake's record) happens before any material is touched, and a failure
while wiring undoes the wiring done so far: nothing is half-applied.
"""

import contextlib
import json
import math
import struct

import bpy

from .prepare import LIGHTMAP_UV, OWNED, BakeError

#: The packed lightmap image's name.
IMAGE_NAME = "Radiosity Lightmap"
#: The node group's name (one for the scene: every material shows the same
#: atlas).
GROUP_NAME = "Radiosity Lightmap"
#: The group node's name in each material.
NODE_NAME = "Radiosity Lightmap"
#: Where a material's previous surface is remembered on the group node.
ORIGINAL = "radiosity_original_surface"


def glb_extras(path):
    """The `extras.radiosity` record of the baked glTF's scene."""
    try:
        with open(path, "rb") as f:
            header = f.read(20)
            if len(header) < 20 or header[:4] != b"glTF":
                raise BakeError(f"{path} is not a binary glTF file")
            length, kind = struct.unpack("<II", header[12:20])
            if kind != 0x4E4F534A:
                raise BakeError(f"{path}: its first chunk is not JSON")
            document = json.loads(f.read(length))
    except (OSError, ValueError) as e:
        raise BakeError(f"cannot read the bake {path}: {e}") from e
    scenes = document.get("scenes") or [{}]
    record = (scenes[document.get("scene", 0)].get("extras") or {}).get("radiosity")
    if not record:
        raise BakeError(f"{path} holds no radiosity record (extras.radiosity)")
    return record


def load_image(path):
    """The EXR at `path` as a new packed image (linear)."""
    try:
        image = bpy.data.images.load(path, check_existing=False)
    except RuntimeError as e:
        raise BakeError(f"cannot read the lightmap {path}: {e}") from e
    try:
        image.colorspace_settings.name = "Linear Rec.709"
    except TypeError:
        pass
    image.pack()
    image[OWNED] = "lightmap"
    return image


def build_group(image, look, scale):
    """The add-on's node group, made or rebuilt: a ``Base Color`` in, a
    shader out, emitting the lightmap (`look` ``LIT``) or the lightmap
    times the base colour times `scale` (``SHADING``)."""
    group = bpy.data.node_groups.get(GROUP_NAME)
    if group is None or group.get(OWNED) != "lightmap group":
        group = bpy.data.node_groups.new(GROUP_NAME, "ShaderNodeTree")
        group[OWNED] = "lightmap group"
    group.nodes.clear()
    group.interface.clear()
    group.interface.new_socket(name="Base Color", in_out="INPUT", socket_type="NodeSocketColor")
    group.interface.new_socket(name="Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    nodes, links = group.nodes, group.links
    inputs = nodes.new("NodeGroupInput")
    inputs.location = (-600, -200)
    outputs = nodes.new("NodeGroupOutput")
    outputs.location = (400, 0)
    uv = nodes.new("ShaderNodeUVMap")
    uv.uv_map = LIGHTMAP_UV
    uv.location = (-600, 100)
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    texture.interpolation = "Linear"
    texture.extension = "EXTEND"
    texture.location = (-400, 100)
    links.new(uv.outputs["UV"], texture.inputs["Vector"])
    emission = nodes.new("ShaderNodeEmission")
    emission.location = (200, 0)
    if look == "SHADING":
        multiply = nodes.new("ShaderNodeVectorMath")
        multiply.operation = "MULTIPLY"
        multiply.location = (0, 0)
        links.new(texture.outputs["Color"], multiply.inputs[0])
        links.new(inputs.outputs["Base Color"], multiply.inputs[1])
        links.new(multiply.outputs["Vector"], emission.inputs["Color"])
        emission.inputs["Strength"].default_value = scale
    else:
        links.new(texture.outputs["Color"], emission.inputs["Color"])
        emission.inputs["Strength"].default_value = 1.0
    links.new(emission.outputs["Emission"], outputs.inputs["Shader"])
    group.interface.items_tree["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    return group


def _output(tree):
    for target in ("ALL", "CYCLES", "EEVEE"):
        node = tree.get_output_node(target)
        if node is not None:
            return node
    return next((n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"), None)


def _owned_node(tree):
    return next((n for n in tree.nodes if n.get(OWNED) == "lightmap node"), None)


def _base_colour(material, tree, original):
    """Where the material's base colour comes from: a socket to link, or a
    colour."""
    bsdf = original if original is not None and original.type == "BSDF_PRINCIPLED" else None
    bsdf = bsdf or next((n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is not None:
        socket = bsdf.inputs["Base Color"]
        if socket.links:
            return socket.links[0].from_socket, None
        return None, tuple(socket.default_value)
    return None, tuple(material.diffuse_color)


def wire(material, group, look, undo):
    """Makes `material`'s surface the group's (see the module's
    documentation); records how to undo it in `undo`."""
    if not material.use_nodes:
        material.use_nodes = True
        undo.append(lambda: setattr(material, "use_nodes", False))
    tree = material.node_tree
    output = _output(tree)
    if output is None:
        output = tree.nodes.new("ShaderNodeOutputMaterial")
        undo.append(lambda: tree.nodes.remove(output))
    surface = output.inputs["Surface"]
    node = _owned_node(tree)
    if node is None:
        original = surface.links[0].from_socket if surface.links else None
        node = tree.nodes.new("ShaderNodeGroup")
        node.name = NODE_NAME
        node.label = "Radiosity Lightmap"
        node[OWNED] = "lightmap node"
        node[ORIGINAL] = json.dumps([original.node.name, original.identifier]) if original else ""
        node.location = (output.location.x - 200, output.location.y - 160)
        undo.append(lambda: _unwire(tree, node, output))
    node.node_tree = group
    original = _original_socket(tree, node)
    source = original.node if original is not None else None
    linked, colour = _base_colour(material, tree, source)
    for link in list(node.inputs["Base Color"].links):
        tree.links.remove(link)
    if linked is not None:
        tree.links.new(linked, node.inputs["Base Color"])
    elif colour is not None:
        node.inputs["Base Color"].default_value = colour
    tree.links.new(node.outputs["Shader"], surface)


def _original_socket(tree, node):
    """The output socket that was the material's surface before the
    add-on's `node` took its place (None if there was none, or it has been
    deleted since)."""
    record = node.get(ORIGINAL, "")
    if not record:
        return None
    name, identifier = json.loads(record)
    source = tree.nodes.get(name)
    if source is None:
        return None
    return next((s for s in source.outputs if s.identifier == identifier), None)


def _unwire(tree, node, output):
    """Removes the add-on's node from `tree`, the previous surface linked
    again."""
    original = _original_socket(tree, node)
    tree.nodes.remove(node)
    if original is not None:
        tree.links.new(original, output.inputs["Surface"])


@contextlib.contextmanager
def original_surfaces(objects):
    """For the time of a ``with`` block, the materials of `objects` that
    show an earlier bake have their previous surfaces linked instead, so a
    new export carries the user's materials, not the baked light as
    emission."""
    swapped = []
    try:
        for material in {s.material for o in objects for s in o.material_slots if s.material}:
            tree = material.node_tree
            node = _owned_node(tree) if tree is not None else None
            output = _output(tree) if node is not None else None
            if output is None:
                continue
            surface = output.inputs["Surface"]
            for link in list(surface.links):
                tree.links.remove(link)
            original = _original_socket(tree, node)
            if original is not None:
                tree.links.new(original, surface)
            swapped.append((tree, node, surface))
        yield
    finally:
        for tree, node, surface in swapped:
            tree.links.new(node.outputs["Shader"], surface)


def apply(objects, bake_path, exr_path, look):
    """Packs the lightmap and wires it into the materials of `objects`."""
    record = glb_extras(bake_path)
    lightmap = record.get("lightmap") or {}
    if lightmap.get("uv_generated", False):
        raise BakeError(
            "the bake could not use the Lightmap UV maps (they overlap, leave the unit square, "
            "or a mesh is drawn twice) and made its own, which Blender's objects do not have: "
            "remove the Lightmap UV maps so the add-on packs them again"
        )
    if look == "SHADING":
        # The EXR holds (E + ambient)/pi x color_scale; the picture shows
        # B x picture_exposure, B = rho (E + ambient).
        scale = math.pi * record["picture_exposure"] / record["color_scale"]
    else:
        scale = 1.0
    image = load_image(exr_path)
    old_image = bpy.data.images.get(IMAGE_NAME)
    undo = []
    try:
        group = build_group(image, look, scale)
        materials = []
        for o in objects:
            for slot in o.material_slots:
                if slot.material is not None and slot.material not in materials:
                    materials.append(slot.material)
        for material in materials:
            wire(material, group, look, undo)
    except Exception:
        for step in reversed(undo):
            step()
        if old_image is not None and old_image.name in bpy.data.images:
            group = bpy.data.node_groups.get(GROUP_NAME)
            if group is not None:
                for node in group.nodes:
                    if node.type == "TEX_IMAGE":
                        node.image = old_image
        bpy.data.images.remove(image)
        raise
    if old_image is not None and old_image != image:
        old_image.user_remap(image)
        bpy.data.images.remove(old_image)
    image.name = IMAGE_NAME
    return len(materials)


def clear():
    """Takes the add-on's lightmap out of every material (their previous
    surfaces back) and removes its node group and image; the ``Lightmap``
    UV maps stay. Returns how many materials were restored."""
    restored = 0
    for material in bpy.data.materials:
        tree = material.node_tree
        if tree is None:
            continue
        node = _owned_node(tree)
        if node is None:
            continue
        output = _output(tree)
        if output is None:
            tree.nodes.remove(node)
        else:
            _unwire(tree, node, output)
        restored += 1
    group = bpy.data.node_groups.get(GROUP_NAME)
    if group is not None and group.get(OWNED):
        bpy.data.node_groups.remove(group)
    image = bpy.data.images.get(IMAGE_NAME)
    if image is not None and image.get(OWNED):
        bpy.data.images.remove(image)
    return restored
