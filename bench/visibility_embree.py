#!/usr/bin/env python3
"""Embree 4 on the segments of `wavrad bench visibility`: the reference ray tracer (issue 19).

Traces the same segments through Embree 4 (PyPI `embreex`, one thread) over every triangle of the
same scene (loaded with PyPI `trimesh`), runs `wavrad bench visibility` on them, and prints both
JSON lines and the ratio of wavrad's rate per thread to Embree's.

A segment [a, b] is occluded when a triangle meets it more than `eps` from both ends, with
eps = 1e-6 x the scene's bounding-box diagonal (wavrad's ENDPOINT_EPSILON_REL): Embree's ray starts
at a + eps d with tfar = |b - a| - 2 eps (embreex fixes tnear at 0, so the origin moves instead).
Embree traces in single precision; the segment files hold f32 coordinates.

Setup (once):
    python3 -m venv /tmp/embree-venv
    /tmp/embree-venv/bin/pip install embreex trimesh numpy
Run (from the repository, with a release build):
    cargo build --release
    target/release/wavrad bench visibility SCENE.glb --generate 1000000 --out /tmp/segments.json
    /tmp/embree-venv/bin/python bench/visibility_embree.py SCENE.glb /tmp/segments.json \
        [--wavrad target/release/wavrad] [--threads 1]

Output: three JSON lines on stdout, {"tracer": "embree", ...}, {"tracer": "wavrad", ...} and
{"occluded_difference": ..., "rate_ratio_per_thread": ...}.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
import trimesh

# wavrad's ENDPOINT_EPSILON_REL (src/solver/visibility/mod.rs).
ENDPOINT_EPSILON_REL = 1e-6
# Rays per call into embreex (bounds the temporary arrays).
BATCH = 1 << 18


def scene_triangles(path):
    """Every triangle of the scene in world space, as (n, 3, 3) float64, and the diagonal."""
    loaded = trimesh.load(path, force="scene", process=False)
    mesh = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded.dump(concatenate=True)
    triangles = np.asarray(mesh.triangles, dtype=np.float64)
    lo = triangles.reshape(-1, 3).min(axis=0)
    hi = triangles.reshape(-1, 3).max(axis=0)
    return triangles, float(np.linalg.norm(hi - lo))


def embree_occluded(triangles, segments, eps):
    """Occluded count and seconds (tracing only) of Embree on one thread."""
    from embreex import mesh_construction, rtcore, rtcore_scene

    scene = rtcore_scene.EmbreeScene(rtcore.EmbreeDevice())
    mesh_construction.TriangleMesh(scene, triangles.astype(np.float32))
    a = segments[:, 0:3]
    d = segments[:, 3:6] - a
    length = np.linalg.norm(d, axis=1)
    live = length > 2.0 * eps
    d[live] /= length[live, None]
    origins = (a + eps * d).astype(np.float32)
    directions = d.astype(np.float32)
    tfar = np.where(live, length - 2.0 * eps, 0.0).astype(np.float32)
    # The first call commits (builds) the scene: not part of the tracing time.
    start = time.perf_counter()
    scene.run(origins[:1], directions[:1], dists=tfar[:1].copy(), query="OCCLUDED")
    build = time.perf_counter() - start
    occluded = 0
    start = time.perf_counter()
    for lo in range(0, len(segments), BATCH):
        hi = min(lo + BATCH, len(segments))
        hits = scene.run(
            origins[lo:hi], directions[lo:hi], dists=tfar[lo:hi].copy(), query="OCCLUDED"
        )
        occluded += int(np.count_nonzero((hits != -1) & live[lo:hi]))
    return occluded, time.perf_counter() - start, build


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene")
    parser.add_argument("segments")
    parser.add_argument("--wavrad", default="target/release/wavrad")
    parser.add_argument("--threads", type=int, default=1, help="wavrad's threads")
    args = parser.parse_args()

    # One core for Embree (its build included), so "one thread" holds whatever TBB would do.
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    with open(args.segments) as f:
        segments = np.asarray(json.load(f), dtype=np.float64).reshape(-1, 6)
    triangles, diagonal = scene_triangles(args.scene)
    eps = ENDPOINT_EPSILON_REL * diagonal
    occluded, seconds, build = embree_occluded(triangles, segments, eps)
    print(
        f"embree: {len(triangles)} triangles, build {build:.3f} s, eps {eps:.3e}",
        file=sys.stderr,
    )
    embree = {
        "tracer": "embree",
        "segments": len(segments),
        "occluded": occluded,
        "seconds": seconds,
        "per_second": len(segments) / seconds,
        "threads": 1,
    }
    print(json.dumps(embree), flush=True)

    # wavrad on every core again.
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, range(os.cpu_count() or 1))
    run = subprocess.run(
        [args.wavrad, "bench", "visibility", args.scene, "--segments", args.segments,
         "--threads", str(args.threads)],
        check=True, capture_output=True, text=True,
    )
    sys.stderr.write(run.stderr)
    wavrad = json.loads(run.stdout)
    wavrad["tracer"] = "wavrad"
    print(json.dumps(wavrad))
    difference = abs(wavrad["occluded"] - occluded) / max(occluded, 1)
    ratio = (wavrad["per_second"] / wavrad["threads"]) / embree["per_second"]
    print(json.dumps({
        "occluded_difference": difference,
        "within_0.1_percent": difference <= 1e-3,
        "rate_ratio_per_thread": ratio,
    }))


if __name__ == "__main__":
    main()
