"""Tables of the automatic level-of-detail chains an `altrep precompute bench/auto.toml` run wrote.

Usage: python3 bench/auto_table.py OUT

For each asset: the automatic chain's bands (sizes, member, triangles, steps per pixel, worst PSNR
at each edge) and, beside it, the chains of meshes only and of impostors only built from the same
candidates: bytes, the objective (`cost`, shader steps, docs/design.md §10c), the largest draw cost
of a band at its top, and the verification's repairs.
"""

import json
import pathlib
import sys


def member(m):
    if m["kind"] == "source":
        return "source"
    if m["kind"] == "mesh":
        return f"level {m['level']}"
    return f"impostor {m['size']}²"


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
        for k in ["auto", "meshes_only", "impostors_only"]:
            c = r[k]
            if c is None:
                row += ["–", "–", "–"]
                continue
            worst = max(b["draw_steps"] for b in c["bands"])
            row += [f"{c['bytes']:,}", f"{c['cost']:,.0f}", f"{worst:,.0f}"]
        row += [f"{r['mesh_s'] + r['impostor_s']:.2f}", f"{r['verify_s']:.2f}"]
        rows.append(row)
    print(
        "| asset | auto bytes | auto cost | auto largest band draw | meshes-only bytes | cost | largest draw "
        "| impostors-only bytes | cost | largest draw | candidates s | verify s |"
    )
    print("|---" * 12 + "|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main(sys.argv[1])
