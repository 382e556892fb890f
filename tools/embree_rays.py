#!/usr/bin/env python3
"""Times Intel Embree's occlusion query on the shadow segments of
`radiosity experiment rays`, for comparison with our BVH and BSP.

Needs numpy and the `embreex` package (Embree 4 bindings), which are not
dependencies of the project; install them in a throw-away environment:

    python3 -m venv /tmp/embree-venv
    /tmp/embree-venv/bin/pip install embreex numpy

`radiosity experiment rays --embree-python /tmp/embree-venv/bin/python`
writes the file and runs this script between its own repetitions. By hand:

    python3 tools/embree_rays.py RAYS.bin [--repetitions N]

The file (little-endian): b"RADRAYS1", the triangle count T and segment
count S as u64, T x 9 f64 triangle corners, S x 6 f64 segment ends (from,
to), S bytes of our answers (1 = blocked).

Each segment becomes a ray from `from` along `to - from` with tnear 0 and
tfar 1 (the segment's length in units of its direction), shortened by 16
f32 units of its largest coordinate at both ends, all in one call of
embreex's batched occlusion query (`EmbreeScene.run(..., query="OCCLUDED")`,
a compiled loop of rtcOccluded1 on the calling thread: one thread, as our
timings). Prints one JSON object: median nanoseconds per ray over the
repetitions, the build time (scene commit, forced by a first one-ray
query), the share of segments where Embree's answer equals ours, and the
count it found blocked.
"""

import argparse
import json
import sys
import time

import numpy as np
from embreex import mesh_construction, rtcore_scene

MAGIC = b"RADRAYS1"


def read_rays(path):
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != MAGIC:
        sys.exit(f"{path}: not a rays file (no {MAGIC!r} header)")
    triangles, segments = np.frombuffer(data, dtype="<u8", count=2, offset=8)
    offset = 24
    tri = np.frombuffer(data, dtype="<f8", count=int(triangles) * 9, offset=offset)
    offset += tri.nbytes
    seg = np.frombuffer(data, dtype="<f8", count=int(segments) * 6, offset=offset)
    offset += seg.nbytes
    answers = np.frombuffer(data, dtype=np.uint8, count=int(segments), offset=offset)
    if offset + answers.nbytes != len(data):
        sys.exit(f"{path}: {len(data)} bytes, expected {offset + answers.nbytes}")
    return tri.reshape(-1, 3, 3), seg.reshape(-1, 2, 3), answers.astype(bool)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rays", help="file written by `radiosity experiment rays`")
    parser.add_argument("--repetitions", type=int, default=1)
    args = parser.parse_args()

    triangles, segments, ours = read_rays(args.rays)
    start, end = segments[:, 0, :], segments[:, 1, :]
    # Our segments are already shortened by 1e-6 of their length at both
    # ends, less than f32 resolves far from the origin; shorten them further
    # by 16 f32 units of their largest coordinate, as a renderer offsets
    # shadow rays, so Embree does not find the source and receiver that we
    # skip by id.
    length = np.linalg.norm(end - start, axis=1)
    scale = np.maximum(np.abs(start).max(axis=1), np.abs(end).max(axis=1))
    eps = np.minimum(16 * np.finfo(np.float32).eps * scale / np.maximum(length, 1e-300), 0.25)
    origins = np.ascontiguousarray(start + (end - start) * eps[:, None], dtype=np.float32)
    directions = np.ascontiguousarray((end - start) * (1 - 2 * eps)[:, None], dtype=np.float32)
    tfar = np.ones(len(origins), dtype=np.float32)

    start = time.perf_counter()
    scene = rtcore_scene.EmbreeScene()
    mesh_construction.TriangleMesh(scene, np.ascontiguousarray(triangles, dtype=np.float32))
    scene.run(origins[:1], directions[:1], dists=tfar[:1], query="OCCLUDED")
    build = time.perf_counter() - start

    times = []
    hits = None
    for _ in range(max(1, args.repetitions)):
        start = time.thread_time()
        hits = scene.run(origins, directions, dists=tfar, query="OCCLUDED")
        times.append(time.thread_time() - start)
    blocked = np.asarray(hits) != -1
    times.sort()
    print(
        json.dumps(
            {
                "ns_per_ray": 1e9 * times[len(times) // 2] / max(1, len(origins)),
                "build_seconds": build,
                "agreement": float(np.mean(blocked == ours)) if len(ours) else 1.0,
                "blocked": int(blocked.sum()),
                "segments": int(len(origins)),
                "triangles": int(len(triangles)),
            }
        )
    )


if __name__ == "__main__":
    main()
