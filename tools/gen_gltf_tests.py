#!/usr/bin/env python3
"""Write the hand-made glTF test scene tests/data/hierarchy.gltf.

A small scene whose every number the tests (crates/radiosity/tests/gltf.rs)
check by hand: a node hierarchy with uniform and negative scale, a rotation
quaternion, a translation and two matrices; a 2x2 sRGB texture; an emissive
strength; a double-sided material; a perspective camera; a
KHR_lights_punctual light (to be ignored with a warning) and a POINTS
primitive (skipped with a warning). The buffer and the texture are separate files beside the .gltf,
so loading also exercises the resolver. Output is byte-identical on every
run.

World geometry (room node scales everything by 2):
  floor  2 x 2 m at y = 0, facing +y, textured (checker.png x 0.8)
  rug    1 x 1 m at y = 0.01, facing +y (mirrored node: winding flips)
  lamp   0.5 x 0.5 m at y = 2.4, facing -y, emissive (1, 0.5, 0.25) x 8
  panel  2 x 2 m in the plane x = -1.2, y in [0, 2], z in [-1, 1], facing
         +x, double-sided
  camera eye (0, 1, 3) looking down -z, yfov 0.8 rad

Usage (from the repository root): python3 tools/gen_gltf_tests.py
"""

import json
import math
import struct
import zlib
from pathlib import Path

OUT = Path(__file__).resolve().parent.parent / "tests" / "data"


def png(width, height, rows):
    """A minimal 8-bit RGB PNG."""
    raw = b"".join(b"\x00" + bytes(row) for row in rows)

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def column_major(rows):
    return [rows[r][c] for c in range(4) for r in range(4)]


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    # Texels (sRGB): red, green / blue, mid grey.
    (OUT / "checker.png").write_bytes(
        png(2, 2, [[255, 0, 0, 0, 255, 0], [0, 0, 255, 128, 128, 128]]))

    positions = [(-0.5, 0, -0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (-0.5, 0, 0.5)]
    uvs = [(0, 0), (1, 0), (1, 1), (0, 1)]
    indices = [0, 3, 2, 0, 2, 1]  # counter-clockwise seen from +y
    bin_data = b"".join(struct.pack("<3f", *p) for p in positions)
    uv_offset = len(bin_data)
    bin_data += b"".join(struct.pack("<2f", *t) for t in uvs)
    index_offset = len(bin_data)
    bin_data += struct.pack("<6H", *indices)
    point_offset = len(bin_data) + 0  # 12 + 32 + 12 = 56, already aligned
    bin_data += struct.pack("<3f", 0, 0, 0)
    (OUT / "hierarchy.bin").write_bytes(bin_data)

    s = math.sqrt(0.5)
    rot_y_90 = [[0, 0, 1, 0], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]]
    # Rz(-90 deg) (+y -> +x), then translate by (-0.6, 0.5, 0).
    panel = [[0, 1, 0, -0.6], [-1, 0, 0, 0.5], [0, 0, 1, 0], [0, 0, 0, 1]]
    quad = {"POSITION": 0, "TEXCOORD_0": 1}
    doc = {
        "asset": {"version": "2.0", "generator": "tools/gen_gltf_tests.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "sun lamp", "type": "point", "color": [1, 1, 1], "intensity": 100}]}},
        "scene": 0,
        "scenes": [{"name": "hierarchy", "nodes": [0]}],
        "nodes": [
            {"name": "room", "scale": [2, 2, 2], "children": [1, 3, 4, 5, 6, 7]},
            {"name": "floor", "matrix": column_major(rot_y_90), "mesh": 0, "children": [2]},
            {"name": "rug", "translation": [0, 0.005, 0], "scale": [-0.5, 1, 0.5], "mesh": 1},
            {"name": "lamp", "translation": [0, 1.2, 0], "rotation": [1, 0, 0, 0],
             "scale": [0.25, 1, 0.25], "mesh": 2},
            {"name": "panel", "matrix": column_major(panel), "mesh": 3},
            {"name": "camera", "translation": [0, 0.5, 1.5], "camera": 0},
            {"name": "sun", "translation": [0, 3, 0],
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "markers", "mesh": 4, "rotation": [0, s, 0, s]},
        ],
        "cameras": [{"name": "view", "type": "perspective",
                     "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.01}}],
        "meshes": [
            {"name": "floor", "primitives": [{"attributes": quad, "indices": 2, "material": 0}]},
            {"name": "rug", "primitives": [{"attributes": quad, "indices": 2, "material": 1}]},
            {"name": "lamp", "primitives": [{"attributes": quad, "indices": 2, "material": 2}]},
            {"name": "panel", "primitives": [{"attributes": quad, "indices": 2, "material": 3}]},
            {"name": "markers", "primitives": [{"attributes": {"POSITION": 3}, "mode": 0}]},
        ],
        "materials": [
            {"name": "checker", "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.8, 0.8, 1], "baseColorTexture": {"index": 0},
                "metallicFactor": 0}},
            {"name": "rug", "pbrMetallicRoughness": {
                "baseColorFactor": [0.5, 0.25, 0.125, 1], "metallicFactor": 0}},
            {"name": "lamp", "emissiveFactor": [1, 0.5, 0.25],
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 8}},
             "pbrMetallicRoughness": {"metallicFactor": 0}},
            {"name": "panel", "doubleSided": True, "pbrMetallicRoughness": {
                "baseColorFactor": [0.2, 0.4, 0.6, 1], "metallicFactor": 0}},
        ],
        "textures": [{"sampler": 0, "source": 0}],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}],
        "images": [{"name": "checker", "uri": "checker.png"}],
        "buffers": [{"uri": "hierarchy.bin", "byteLength": len(bin_data)}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48, "target": 34962},
            {"buffer": 0, "byteOffset": uv_offset, "byteLength": 32, "target": 34962},
            {"buffer": 0, "byteOffset": index_offset, "byteLength": 12, "target": 34963},
            {"buffer": 0, "byteOffset": point_offset, "byteLength": 12, "target": 34962},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-0.5, 0, -0.5], "max": [0.5, 0, 0.5]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5126, "count": 1, "type": "VEC3",
             "min": [0, 0, 0], "max": [0, 0, 0]},
        ],
    }
    (OUT / "hierarchy.gltf").write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {OUT / 'hierarchy.gltf'}, hierarchy.bin, checker.png")


if __name__ == "__main__":
    main()
