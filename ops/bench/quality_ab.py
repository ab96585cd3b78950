#!/usr/bin/env python3
"""Which outputs of `sparc3d convert` change between two binaries, and how their quality moves
(docs/QUALITY.md).

For every mesh of CORPUS (a folder), converts it with binary A and binary B at one resolution
(`convert --json`, default parameters of each binary), and compares the two output files byte
for byte. Meshes whose outputs differ are measured against their source with `B eval
--resolution N --json` (the same `eval` for both outputs, at each of --seeds), and one JSON
line per mesh goes to OUT.jsonl: whether the bytes differ, both convert summaries (watertight,
manifold, components, stage seconds, B's `sealed_pockets`) and, for changed meshes, both
evaluations. `--summarize OUT.jsonl` prints the changed meshes with their F1 @ 0.005, Chamfer
(× N) and components kept before and after, sorted by the change in F1, and the counts.

    python3 ops/bench/quality_ab.py CORPUS --a OLD_BIN --b NEW_BIN --resolution 256 --out ab256
    python3 ops/bench/quality_ab.py --summarize ab256.jsonl
    python3 ops/bench/quality_ab.py CORPUS --a BIN --b BIN --b-flags=--refine --out refine256

Only the standard library.
"""

import argparse
import concurrent.futures
import filecmp
import json
import os
import sys
import tempfile

from benchlib import MESH_EXTENSIONS, last_json



def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("corpus", nargs="?", help="folder of meshes")
    p.add_argument("--a", help="binary A (before)")
    p.add_argument("--b", help="binary B (after)")
    p.add_argument("--resolution", type=int, default=256)
    p.add_argument("--b-flags", default="",
                   help="extra `convert` flags for B, space-separated (e.g. --refine, with --b the same binary as --a)")
    p.add_argument("--samples", type=int, default=100_000,
                   help="points `eval` samples on each mesh (more: less noise, slower)")
    p.add_argument("--seeds", default=str(0x5BA3C3D0),
                   help="eval seeds for changed meshes, comma-separated (default: eval's own)")
    p.add_argument("--out", default="quality_ab", help="output prefix: PREFIX.jsonl")
    p.add_argument("--jobs", type=int, default=1, help="meshes at once")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds per command")
    p.add_argument("--keep", metavar="DIR", help="keep both outputs of changed meshes in DIR")
    p.add_argument("--summarize", metavar="JSONL", help="only summarise an existing results file")
    return p.parse_args()


def evaluate(args, mesh, out):
    """`eval` of one output at every seed: a list of reports (or errors)."""
    reports = []
    for seed in args.seeds.split(","):
        cmd = [args.b, "eval", mesh, out, "--resolution", str(args.resolution), "--json",
               "--seed", seed.strip(), "--samples", str(args.samples)]
        report, _, err = last_json(cmd, args.timeout)
        reports.append({"seed": int(seed), "error": err} if err else {"seed": int(seed), **report})
    return reports


def measure(args, mesh):
    """Both conversions of one mesh, and both evaluations when the outputs differ."""
    record = {"mesh": os.path.basename(mesh), "resolution": args.resolution}
    with tempfile.TemporaryDirectory() as tmp:
        outs = {}
        for side, binary in (("a", args.a), ("b", args.b)):
            out = os.path.join(tmp, f"{side}.ply")
            cmd = [binary, "convert", mesh, "-o", out, "--resolution", str(args.resolution), "--json"]
            if side == "b":
                cmd += args.b_flags.split()
            summary, _, err = last_json(cmd, args.timeout)
            record[side] = {"error": err} if err else {"convert": summary}
            outs[side] = out if not err else None
        if not (outs["a"] and outs["b"]):
            return record
        record["changed"] = not filecmp.cmp(outs["a"], outs["b"], shallow=False)
        if record["changed"]:
            for side in ("a", "b"):
                record[side]["eval"] = evaluate(args, mesh, outs[side])
            if args.keep:
                stem = os.path.splitext(record["mesh"])[0]
                for side in ("a", "b"):
                    os.replace(outs[side], os.path.join(args.keep, f"{stem}.{side}.ply"))
    return record


def f1(report, threshold=0.005):
    for score in report.get("f1", []):
        if abs(score.get("threshold", -1) - threshold) < 1e-9:
            return score.get("f1")
    return None


def mean(values):
    values = [v for v in values if v is not None]
    return sum(values) / len(values) if values else None


def side_figures(entry):
    reports = [r for r in entry.get("eval", []) if "error" not in r]
    return {
        "f1": mean([f1(r) for r in reports]),
        "cd_voxels": mean([r.get("cd_voxels") for r in reports]),
        "kept": reports[0].get("components_kept") if reports else None,
        "total": reports[0].get("components_total") if reports else None,
    }


def summarize(path):
    rows = [json.loads(line) for line in open(path) if line.strip()]
    changed = [r for r in rows if r.get("changed")]
    errors = [r for r in rows if "error" in r.get("a", {}) or "error" in r.get("b", {})]
    print(f"{len(rows)} meshes at {rows[0]['resolution'] if rows else '?'}³: "
          f"{len(changed)} outputs changed, {len(errors)} with a conversion error")
    table = []
    for r in changed:
        a, b = side_figures(r["a"]), side_figures(r["b"])
        conv = r["b"]["convert"]
        table.append((r["mesh"], a, b, conv.get("sealed_pockets"), conv.get("watertight"), conv.get("manifold")))
    table.sort(key=lambda t: (t[2]["f1"] or 0) - (t[1]["f1"] or 0))
    print(f"{'mesh':44} {'F1 a':>7} {'F1 b':>7} {'ΔF1':>7} {'CD a':>7} {'CD b':>7} {'kept a':>7} {'kept b':>7} sealed wt mf")
    for name, a, b, sealed, wt, mf in table:
        d = (b["f1"] or 0) - (a["f1"] or 0)
        print(f"{name[:44]:44} {a['f1'] or 0:7.2f} {b['f1'] or 0:7.2f} {d:+7.2f} "
              f"{a['cd_voxels'] or 0:7.3f} {b['cd_voxels'] or 0:7.3f} "
              f"{a['kept']}/{a['total']:<5} {b['kept']}/{b['total']:<5} {sealed} {wt} {mf}")
    for r in errors:
        print(f"error: {r['mesh']}: {r['a'].get('error') or r['b'].get('error')}")


def main():
    args = parse_args()
    if args.summarize:
        summarize(args.summarize)
        return 0
    if not (args.corpus and args.a and args.b):
        sys.exit("give CORPUS, --a and --b (or --summarize JSONL)")
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
    meshes = sorted(
        os.path.join(args.corpus, f) for f in os.listdir(args.corpus)
        if os.path.splitext(f)[1].lower() in MESH_EXTENSIONS
    )
    with open(args.out + ".jsonl", "w") as out, concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        for i, record in enumerate(pool.map(lambda m: measure(args, m), meshes)):
            out.write(json.dumps(record) + "\n")
            out.flush()
            flag = "changed" if record.get("changed") else "same"
            print(f"[{i + 1}/{len(meshes)}] {record['mesh']}: {flag}", file=sys.stderr)
    summarize(args.out + ".jsonl")
    return 0


if __name__ == "__main__":
    sys.exit(main())
