#!/usr/bin/env python3
"""Per-asset table of a precompute run over real assets (docs/real-assets.md).

Usage:
    altrep precompute SCENE.toml --out OUT --allow-below-quality --profile
    python3 bench/real_assets_table.py OUT/report.json [SCENE.toml]

Prints one row per asset: the mesh file's triangles/materials/textures/alpha modes (read from
its glTF JSON when SCENE.toml is given), then per representation the mean PSNR and IoU against
the ray-cast truth, the bytes written, and the asset's mesh-to-files seconds (from --profile).
Standard library only.
"""
import json
import pathlib
import struct
import sys
import tomllib


def gltf_json(path):
    data = path.read_bytes()
    if data[:4] == b"glTF":
        n = struct.unpack_from("<I", data, 12)[0]
        return json.loads(data[20 : 20 + n])
    return json.loads(data)


def inventory(scene_path):
    out = {}
    if scene_path is None:
        return out
    scene = tomllib.loads(pathlib.Path(scene_path).read_text())
    base = pathlib.Path(scene_path).parent
    for a in scene.get("asset", []):
        mesh = a.get("mesh")
        if not mesh or not mesh.lower().endswith((".gltf", ".glb")):
            continue
        j = gltf_json(base / mesh)
        modes = sorted({m.get("alphaMode", "OPAQUE") for m in j.get("materials", [])})
        out[a["name"]] = (len(j.get("materials", [])), len(j.get("textures", [])), "/".join(modes))
    return out


def main():
    report = json.loads(pathlib.Path(sys.argv[1]).read_text())
    inv = inventory(sys.argv[2] if len(sys.argv) > 2 else None)
    reprs = []
    rows = {}
    for o in report["outcomes"]:
        r = o["representation"]
        if r not in reprs:
            reprs.append(r)
        m = o.get("measurement")
        outcome = o["outcome"] if isinstance(o["outcome"], str) else next(iter(o["outcome"]))
        if outcome in ("built", "cached") and m:
            cell = f"{m['psnr_db']:.2f} / {m['iou']:.3f}"
        else:
            cell = outcome
        rows.setdefault(o["asset"], {})[r] = (cell, o["bytes"])
    seconds = {}
    prof = report.get("profile")
    if prof:
        for a in prof.get("assets", []):
            seconds[a["asset"]] = a["total_seconds"]
    head = ["asset", "materials", "textures", "alpha"] + [f"{r} PSNR dB / IoU" for r in reprs]
    head += ["bytes", "mesh to files, s"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for asset, cells in rows.items():
        mats, texs, modes = inv.get(asset, ("", "", ""))
        line = [asset, str(mats), str(texs), modes]
        line += [cells.get(r, ("–", 0))[0] for r in reprs]
        line.append(str(sum(b for _, b in cells.values())))
        line.append(f"{seconds[asset]:.2f}" if asset in seconds else "")
        print("| " + " | ".join(line) + " |")


if __name__ == "__main__":
    main()
