#!/usr/bin/env python3
"""Images with parallax (N = 8, 64²) against the 64-view blend, on every mesh of a scene.

Usage:
    python3 bench/real_assets_vs_blend.py SCENE.toml [--altrep target/release/altrep]

Runs `altrep parallax --mesh M --quality-sweep --quality-views 8 --quality-sizes 64` for each
`mesh` asset of SCENE.toml (up axis and node as the manifest says) and prints, per asset, the
PSNR and IoU against the ray-cast truth of the default reconstruction at N = 8 and of the
64-view blend (with and without the row filter), and their difference. Standard library only.
"""
import argparse
import pathlib
import statistics
import subprocess
import tomllib


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--altrep", default="target/release/altrep")
    args = ap.parse_args()
    scene_path = pathlib.Path(args.scene)
    scene = tomllib.loads(scene_path.read_text())
    print(
        "| asset | N = 8 PSNR dB / IoU | 64-view blend | 64-view blend, row filter |"
        " N = 8 − blend (row filter), dB |"
    )
    print("|---|---|---|---|---|")
    diffs = []
    for a in scene.get("asset", []):
        if "mesh" not in a:
            continue
        cmd = [args.altrep, "parallax", "--mesh", str(scene_path.parent / a["mesh"])]
        cmd += ["--quality-sweep", "--quality-views", "8", "--quality-sizes", "64"]
        if "up" in a:
            cmd += ["--up", a["up"]]
        if "node" in a:
            cmd += ["--node", a["node"]]
        out = subprocess.run(cmd, capture_output=True, text=True).stdout

        def row(name):
            for line in out.splitlines():
                if line.startswith("| " + name + " |"):
                    c = [x.strip() for x in line.strip("|").split("|")]
                    return float(c[3]), float(c[4])
            return None

        d = row("inverse warp (default)")
        b = row("blend 64 views")
        f = row("blend 64 views, row filter")
        if not (d and b and f):
            print(f"| {a['name']} | failed | | | |")
            continue
        diffs.append(d[0] - f[0])
        print(
            f"| {a['name']} | {d[0]:.2f} / {d[1]:.4f} | {b[0]:.2f} / {b[1]:.4f} |"
            f" {f[0]:.2f} / {f[1]:.4f} | {d[0] - f[0]:+.2f} |"
        )
    if diffs:
        print(
            f"\nmean difference {statistics.mean(diffs):+.2f} dB over {len(diffs)} assets;"
            f" worst {min(diffs):+.2f} dB"
        )


if __name__ == "__main__":
    main()
