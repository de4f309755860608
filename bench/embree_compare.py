#!/usr/bin/env python3
"""Cast the rays of `altrep capture --views 8 --size 512` with Embree and with altrep, in one run.

Usage: python3 bench/embree_compare.py [--views 8] [--size 512] [--repeat 5]
                                       [--altrep PATH] [MESH.obj ...]

The speed goal for ray casting is at least Embree's rays per second per core on the shipped
meshes (teapot, beetle, Stanford bunny by default, from ../shared/data/meshes). This script measures both on
this machine, in the same minutes:

- altrep: `altrep capture --mesh M --views V --size S` with RAYON_NUM_THREADS=1 (one core), the
  rate it prints (the capture's tracing and sampling; load and file writing excluded), median
  of --repeat runs;
- Embree (the `embreex` binding, Embree 4, from PyPI), called from Python on one thread: the
  same mesh, normalised into the bounding cylinder R = 1, H = 2 exactly as altrep normalises it
  (data-gen/src/mesh.rs), the same orthographic rays (data-gen/src/geometry.rs: view k looks
  along -d(2πk/V), d(α) = (cos α, 0, sin α), one ray per pixel centre, starting 2R in front of
  the screen point, hit window (0, 4R)), asking for the hit distance, barycentrics, primitive
  and geometric normal; best of --repeat runs of `EmbreeScene.run` (scene build excluded).

It checks that both cast the same rays: per view, the pixels altrep's depth file marks as hit
against Embree's hits, and the depths where both hit (altrep's 16-bit depth, one step =
2/65534 R): a difference of more than 4 steps means the two found different surfaces (for
example a ray through an edge that altrep's Möller–Trumbore test rejects on both triangles
and Embree's watertight test does not). It prints, per mesh, both rates, their ratio, and the
differing pixels.

The script makes its own virtualenv (bench/.venv-embree: numpy, embreex, pillow from PyPI) and
re-runs itself inside it.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from venvs import ensure_venv

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MESHES = os.path.join(ROOT, "..", "shared", "data", "meshes")


def load_obj(path):
    """Triangle corners (n, 3, 3) in f64, polygons split as fans, as tobj triangulates them."""
    import numpy as np

    verts, tris = [], []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                verts.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                n = len(verts)
                idx = []
                for p in parts[1:]:
                    i = int(p.split("/")[0])
                    idx.append(i - 1 if i > 0 else n + i)
                for k in range(1, len(idx) - 1):
                    tris.append((idx[0], idx[k], idx[k + 1]))
    v = np.asarray(verts, dtype=np.float64)
    return v[np.asarray(tris, dtype=np.int64)]


def normalise(corners, radius=1.0, height=2.0):
    """altrep's normalisation (data-gen/src/mesh.rs), to f32; zero-area triangles dropped."""
    import numpy as np

    pts = corners.reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = np.array([0.5 * (lo[0] + hi[0]), lo[1], 0.5 * (lo[2] + hi[2])])
    d = pts - centre
    max_radius = np.sqrt(d[:, 0] ** 2 + d[:, 2] ** 2).max()
    h = hi[1] - lo[1]
    scale = min(radius / max_radius, height / h) * (1.0 - 1e-6)
    lift = 0.5 * (height - h * scale)
    out = ((corners - centre) * scale + np.array([0.0, lift, 0.0])).astype(np.float32)
    area = np.cross(out[:, 1] - out[:, 0], out[:, 2] - out[:, 0])
    return out[(area.astype(np.float32) ** 2).sum(axis=1) > 0]


def view_rays(k, views, size, radius=1.0, height=2.0):
    """Origins and directions (f32, row-major, row 0 at the top) of view k."""
    import numpy as np

    a = 2.0 * np.pi * k / views
    d = np.array([np.cos(a), 0.0, np.sin(a)])
    right = np.array([np.sin(a), 0.0, -np.cos(a)])
    x = -radius + (np.arange(size) + 0.5) * (2.0 * radius / size)
    y = height - (np.arange(size) + 0.5) * (height / size)
    origin = (
        x[None, :, None] * right[None, None, :]
        + y[:, None, None] * np.array([0.0, 1.0, 0.0])[None, None, :]
        + 2.0 * radius * d
    ).reshape(-1, 3)
    dirs = np.broadcast_to(-d, origin.shape)
    return origin.astype(np.float32), np.ascontiguousarray(dirs, dtype=np.float32)


def embree(tris, views, size, repeat):
    """Best time of `repeat` runs over all views, and each view's hits and t (NaN on a miss)."""
    import numpy as np
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tris)
    rays = [view_rays(k, views, size) for k in range(views)]
    best, result = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = [
            scene.run(o, d, dists=np.full(len(o), 4.0, dtype=np.float32), output=1)
            for o, d in rays
        ]
        best = min(best, time.perf_counter() - t0)
        result = out
    views_t = []
    for r in result:
        hit = r["geomID"] != np.array(-1).astype(r["geomID"].dtype)
        views_t.append(np.where(hit, r["tfar"].astype(np.float64), np.nan))
    return best, views_t


def altrep_capture(exe, mesh, views, size, repeat, out):
    """Median one-thread rate of `altrep capture`, and the capture's folder."""
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    rates = []
    for _ in range(repeat):
        subprocess.check_call(
            exe + ["capture", "--mesh", mesh, "--views", str(views), "--size", str(size),
                   "--out", out],
            env=env, stdout=subprocess.DEVNULL,
        )
        with open(os.path.join(out, "capture.json")) as f:
            rates.append(json.load(f)["rays_per_second"])
    return statistics.median(rates), out


def compare(out, views_t, size, steps=4.0):
    """Pixels hit by one side only; pixels hit by both whose depths differ by more than
    `steps` 16-bit steps (another surface); the largest difference among the others."""
    import numpy as np
    from PIL import Image

    with open(os.path.join(out, "capture.json")) as f:
        files = json.load(f)["files"]
    one_side, other_surface, worst = 0, 0, 0.0
    for f, t in zip(files, views_t):
        png = np.asarray(Image.open(os.path.join(out, f["depth16"])), dtype=np.float64)
        png = png.reshape(-1)
        ours = png != 0
        theirs = ~np.isnan(t)
        one_side += int((ours != theirs).sum())
        both = ours & theirs
        # depth = (2R - t)/R with R = 1, stored as 1 + (depth + 1)/2 · 65534.
        theirs_png = 1.0 + ((2.0 - t[both]).clip(-1, 1) + 1.0) * 0.5 * 65534.0
        diff = np.abs(theirs_png - png[both])
        other_surface += int((diff > steps).sum())
        if (diff <= steps).any():
            worst = max(worst, float(diff[diff <= steps].max()))
    return one_side, other_surface, worst


def main():
    ensure_venv(".venv-embree", ["numpy", "embreex", "pillow"], __file__)
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("meshes", nargs="*")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--altrep", help="path of a built altrep binary (default: cargo run --release)")
    args = ap.parse_args()
    meshes = args.meshes or [
        os.path.join(MESHES, f"{m}.obj") for m in ["teapot", "beetle", "stanford-bunny"]
    ]
    missing = [m for m in meshes if not os.path.exists(m)]
    if missing:
        sys.exit(f"mesh not found: {', '.join(missing)} (the shipped meshes live in ../shared)")
    exe = [args.altrep] if args.altrep else [
        "cargo", "run", "--quiet", "--release", "--manifest-path",
        os.path.join(ROOT, "Cargo.toml"), "--",
    ]
    rays = args.views * args.size * args.size
    print(f"{args.views} views of {args.size}², {rays} rays per pass, one thread each; "
          f"altrep: median of {args.repeat} captures, Embree: best of {args.repeat} passes\n")
    print("| mesh | triangles | altrep, M rays/s | Embree, M rays/s | altrep ÷ Embree "
          "| hit by one side only | another surface hit (depths > 4 steps apart) "
          "| largest depth difference otherwise (16-bit steps) |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for mesh in meshes:
            name = os.path.splitext(os.path.basename(mesh))[0]
            tris = normalise(load_obj(mesh))
            ours, out = altrep_capture(exe, mesh, args.views, args.size, args.repeat,
                                       os.path.join(tmp, name))
            best, views_t = embree(tris, args.views, args.size, args.repeat)
            theirs = rays / best
            one_side, other, worst = compare(out, views_t, args.size)
            print(f"| {name} | {len(tris)} | {ours / 1e6:.2f} | {theirs / 1e6:.2f} | "
                  f"{ours / theirs:.2f}× | {one_side} of {rays} | {other} | {worst:.1f} |",
                  flush=True)


if __name__ == "__main__":
    main()
