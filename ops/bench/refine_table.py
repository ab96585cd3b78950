#!/usr/bin/env python3
"""The refinement's table (docs/QUALITY.md, "Refinement against renderings") from a
`quality_ab.py --b-flags=--refine` run and a `cad_like.py` classification.

    python3 ops/bench/refine_table.py ab256.jsonl cad.json [--samples 1000000]

Prints, per group (CAD-like, the others), the median of each metric without and with the
refinement (mean over the eval seeds), how many meshes moved beyond noise (`NOISE`, scaled
by √(100,000 / samples) when `eval` sampled more points (`quality_ab.py --samples`; sampling
noise falls as one over the root of the sample count), or the seeds' own spread when
larger), and the conversion time per mesh on and off (same run). Only the standard library.
"""
import argparse
import json
import math
import statistics

# The spread of `eval` over four seeds of one output (the largest over chassis_differential,
# bad-stl-tardis and bunny00 at 256³, docs/QUALITY.md): a change smaller than this is noise.
# `cd_surface` was not in that measurement: it borrows the sampled CD's floor, and the seeds'
# own spread decides where that is larger.
NOISE = {"anc": 0.08, "f1_002": 0.41, "f1_005": 0.13, "cd": 0.002, "cd_surface": 0.002}


def figures(reports):
    ok = [r for r in reports if "error" not in r]
    f1 = lambda r, t: next(s["f1"] for s in r["f1"] if abs(s["threshold"] - t) < 1e-9)
    cols = {
        "anc": [r["anc"] for r in ok],
        "f1_002": [f1(r, 0.002) for r in ok],
        "f1_005": [f1(r, 0.005) for r in ok],
        "cd": [r["cd_voxels"] for r in ok],
        # Point-to-triangle, so without the floor of two samplings (docs/QUALITY.md).
        "cd_surface": [r["cd_surface"] * r["options"]["resolution"] for r in ok],
    }
    return {k: (statistics.mean(v), max(v) - min(v)) for k, v in cols.items() if v}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("results", help="quality_ab.py's OUT.jsonl")
    ap.add_argument("cad", help="cad_like.py's classification (JSON)")
    ap.add_argument("--samples", type=int, default=100_000, help="the run's `eval --samples`")
    args = ap.parse_args()
    floor = {k: v * math.sqrt(100_000 / args.samples) for k, v in NOISE.items()}
    rows = [json.loads(line) for line in open(args.results) if line.strip()]
    cad = {k for k, v in json.load(open(args.cad)).items()
           if v.get("curved_share", 9) < 0.1 and v.get("sharp_len_rel", 0) >= 1}
    groups = {"CAD-like": [], "other": []}
    for r in rows:
        if "eval" not in r.get("a", {}) or "eval" not in r.get("b", {}):
            continue
        groups["CAD-like" if r["mesh"] in cad else "other"].append(r)
    print("| group | meshes | metric | off (median) | on (median) | better / worse beyond noise |")
    print("|---|---|---|---|---|---|")
    for name, rs in groups.items():
        if not rs:
            continue
        for key, label, higher in (("anc", "ANC", True), ("f1_002", "F1 @ 0.002", True),
                                   ("f1_005", "F1 @ 0.005", True), ("cd", "CD × N", False),
                                   ("cd_surface", "CD to the surface × N", False)):
            off, on, better, worse = [], [], 0, 0
            for r in rs:
                a, b = figures(r["a"]["eval"]), figures(r["b"]["eval"])
                off.append(a[key][0])
                on.append(b[key][0])
                spread = max(a[key][1], b[key][1], floor[key])
                d = (b[key][0] - a[key][0]) * (1 if higher else -1)
                better += d > spread
                worse += -d > spread
            print(f"| {name} | {len(rs)} | {label} | {statistics.median(off):.3f} | "
                  f"{statistics.median(on):.3f} | {better} / {worse} |")
    print()
    print("| mesh | ANC off → on | F1 @ 0.002 off → on | CD × N off → on | watertight, manifold on | seconds off → on | outcome |")
    print("|---|---|---|---|---|---|---|")
    for name, rs in groups.items():
        for r in sorted(rs, key=lambda r: r["mesh"]):
            a, b = figures(r["a"]["eval"]), figures(r["b"]["eval"])
            ca, cb = r["a"]["convert"], r["b"]["convert"]
            ref = cb.get("refine") or {}
            print(f"| {r['mesh'][:60]}{' (CAD)' if name == 'CAD-like' else ''} | "
                  f"{a['anc'][0]:.2f} → {b['anc'][0]:.2f} | {a['f1_002'][0]:.2f} → {b['f1_002'][0]:.2f} | "
                  f"{a['cd'][0]:.3f} → {b['cd'][0]:.3f} | {cb['watertight']}, {cb['manifold']} | "
                  f"{ca['total_seconds']:.2f} → {cb['total_seconds']:.2f} | {ref.get('outcome')} |")
    times = [(r["a"]["convert"]["total_seconds"], r["b"]["convert"]["total_seconds"])
             for rs in groups.values() for r in rs]
    if times:
        print()
        print(f"median seconds per mesh off {statistics.median(t[0] for t in times):.2f}, "
              f"on {statistics.median(t[1] for t in times):.2f}, "
              f"median ratio {statistics.median(t[1] / t[0] for t in times):.1f}")


if __name__ == "__main__":
    main()
