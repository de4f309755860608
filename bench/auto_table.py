"""Tables of the automatic level-of-detail chains an `altrep precompute bench/auto.toml` run wrote.

Usage: python3 bench/auto_table.py OUT

For each asset: the automatic chain's bands (sizes, member, triangles, steps per pixel, worst PSNR
at each edge) and, beside it, the single-family chains built from the same candidates (simplified
meshes, images with parallax, frames over the sphere, and the engines' octahedral impostor of the
same frames, the baseline): bytes and the objective (`cost`, shader steps, docs/design.md §10c);
then the ratios of the automatic chain's cost and bytes to the cheapest single family's.
"""

import json
import pathlib
import sys


def member(m):
    if m["kind"] == "source":
        return "source"
    if m["kind"] == "mesh":
        return f"level {m['level']}"
    return f"{m['kind']} {m['size']}²"


def main(out):
    rows = []
    for path in sorted(pathlib.Path(out).glob("*/auto/asset.json")):
        d = json.loads(path.read_text())
        r = d["report"]["build"]
        name = path.parent.parent.name
        print(f"### {name} (target {r['target_db']} dB)")
        auto = r["auto"]
        print("| band (px) | member | triangles | steps/pixel | worst dB at the edges |")
        print("|---|---|---|---|---|")
        for b, band in enumerate(auto["bands"]):
            edges = [f"{e[2]:.2f} ({e[1]} px)" for e in auto["edges_worst_db"] if e[0] == b]
            print(
                f"| {band['from_px']:g}–{band['to_px']:g} | {member(band['member'])} | "
                f"{band['triangles']:,} | {band['steps_per_pixel']:.2f} | {', '.join(edges) or '(truth)'} |"
            )
        print()
        row = [name]
        singles = []
        for k in FAMILIES:
            c = r.get(k)
            if c is None:
                row += ["–", "–"]
                continue
            row += [f"{c['bytes']:,}", f"{c['cost']:,.0f}"]
            # A chain of the source alone is no family's stand-in: not compared.
            if k != "auto" and any(b["member"]["kind"] != "source" for b in c["bands"]):
                singles.append((c["cost"], c["bytes"], k))
        if singles:
            cheapest = min(singles)
            row += [
                cheapest[2].replace("_only", ""),
                f"{auto['cost'] / cheapest[0]:.3f}",
                f"{auto['bytes'] / max(cheapest[1], 1):.3f}",
            ]
        else:
            row += ["none draws a stand-in", "–", "–"]
        row += [
            f"{r['mesh_s'] + r['impostor_s'] + r.get('frames_s', 0):.2f}",
            f"{r['verify_s']:.2f}",
        ]
        rows.append(row)
    print(
        "| asset | auto bytes | cost | meshes bytes | cost | parallax bytes | cost | frames bytes | cost "
        "| engine bytes | cost | cheapest single | auto/it cost | auto/it bytes | candidates s | verify s |"
    )
    print("|---" * 16 + "|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


FAMILIES = ["auto", "meshes_only", "impostors_only", "frames_only", "engine_only"]

if __name__ == "__main__":
    main(sys.argv[1])
