#!/usr/bin/env python3
"""How far a measured direction choice falls below the best of the three slice directions
between the angles it was measured at (docs/design.md §9, bench/RESULTS.md "The direction rule,
measured").

Reads the JSON of a sweep at 5° steps:

    altrep slices --angles 0,5,10,15,20,25,30,35,40,45,50,55,60,65,70,75,80,85 --json sweep.json
    python3 bench/direction_table.py sweep.json

The angles that are multiples of 10° are the table's nodes, where each direction's PSNR (at the
level the criterion picks for it) is known; the odd multiples of 5° are checked. Three choices:
the paper's rule (what `altrep slices` draws), the best direction at the nearest node, and the
best of the directions' PSNRs interpolated linearly between the two nodes. Printed per tile:
the worst and the mean shortfall (dB) below the best direction at the checked angles.
"""
import collections
import json
import sys


def main(path):
    rows = json.load(open(path))["sweep"]
    groups = collections.defaultdict(dict)
    for r in rows:
        groups[(r["tile"], r["pixel_voxels"], r["side"])][r["angle_deg"]] = r
    short = collections.defaultdict(list)
    for (tile, _, _), g in groups.items():
        nodes = [a for a in sorted(g) if a % 10 == 0]
        for a in sorted(g):
            lower = [n for n in nodes if n < a]
            upper = [n for n in nodes if n > a]
            if a % 10 == 0 or not lower or not upper:
                continue
            lo, hi = max(lower), min(upper)
            row = g[a]
            best = max(row["psnr_axis"])
            near = lo if a - lo <= hi - a else hi
            pick = max(range(3), key=lambda i: g[near]["psnr_axis"][i])
            t = (a - lo) / (hi - lo)
            interp = max(
                range(3),
                key=lambda i: (1 - t) * g[lo]["psnr_axis"][i] + t * g[hi]["psnr_axis"][i],
            )
            short[(tile, "rule")].append(best - row["psnr_three"])
            short[(tile, "nearest node")].append(best - row["psnr_axis"][pick])
            short[(tile, "interpolated")].append(best - row["psnr_axis"][interp])
    print("| tile | choice | worst (dB) | mean (dB) | angles checked |")
    print("|---|---|---|---|---|")
    for (tile, how), v in sorted(short.items()):
        print(f"| {tile} | {how} | {max(v):.2f} | {sum(v) / len(v):.2f} | {len(v)} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: direction_table.py SWEEP.json")
    main(sys.argv[1])
