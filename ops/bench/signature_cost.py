#!/usr/bin/env python3
"""The cost of the shape signature in the conversion (issue 44's bar: at most 5 % of the
conversion per item), over a folder of meshes (the dev corpus).

Each mesh is converted twice back to back by the same binary, without and with
`--shape-signature` (the order alternating from one mesh to the next), at one resolution. A
job converts an item through the same path (`sparc3d_workers::convert`) with the signature
on or off as its `shape_signature` key says. From `convert --json`'s `stage_seconds`:

- the conversion: every stage of the run without the signature but the output file's
  `check` and `save` (`convert`'s own; a job encodes instead): load, the conversion stages,
  extraction and the quality facts;
- the share: the `signature` stage of the run with it over that conversion;
- the A/B share: the difference of the two runs' conversions over the one without, which also
  holds whatever the signature changes outside its stage (it is noise-dominated on a shared
  machine: each pair is back to back so both runs see the same load, but a few per cent is
  within one run's spread).

    cargo build --release -p sparc3d
    python3 ops/bench/signature_cost.py /tmp/corpus42/dev --resolution 256 --out sig256.jsonl

Prints a Markdown table of every item and the median and summed shares.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

from benchlib import MESH_EXTENSIONS, Results, add_binary_argument, add_record_argument, binary

NOT_CONVERSION = {"check", "save", "signature"}


def convert(binary, path, resolution, signature, scratch):
    """`convert --json`'s summary, or None when it fails (said on stderr)."""
    out = os.path.join(scratch, "out.ply")
    cmd = [binary, "convert", path, "-o", out, "--resolution", str(resolution), "--json"]
    if signature:
        cmd.append("--shape-signature")
    run = subprocess.run(cmd, capture_output=True, text=True)
    if os.path.exists(out):
        os.remove(out)
    if run.returncode != 0:
        tail = (run.stderr or run.stdout).strip().splitlines()[-1:]
        print(f"{os.path.basename(path)}: {' '.join(tail)}", file=sys.stderr)
        return None
    return json.loads(run.stdout.strip().splitlines()[-1])


def conversion_seconds(summary):
    return sum(v for k, v in summary["stage_seconds"].items() if k not in NOT_CONVERSION)


def measure(binary, path, resolution, signature_first, scratch):
    """One mesh's pair of runs as a row, or None."""
    order = [True, False] if signature_first else [False, True]
    runs = {}
    for signature in order:
        runs[signature] = convert(binary, path, resolution, signature, scratch)
        if runs[signature] is None:
            return None
    plain, signed = runs[False], runs[True]
    base = conversion_seconds(plain)
    stage = signed["stage_seconds"].get("signature", 0.0)
    return {
        "item": os.path.basename(path),
        "output_faces": signed["output_faces"],
        "conversion_s": base,
        "conversion_with_s": conversion_seconds(signed),
        "signature_s": stage,
        "share": stage / base if base > 0 else 0.0,
        "ab_share": (conversion_seconds(signed) + stage - base) / base if base > 0 else 0.0,
    }


def print_table(rows, resolution):
    print("| item | output faces | conversion s (without) | signature s | share | A/B share |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        print(f"| `{r['item']}` | {r['output_faces']} | {r['conversion_s']:.3f} | "
              f"{r['signature_s'] * 1000:.1f} ms | {100 * r['share']:.2f} % | "
              f"{100 * r['ab_share']:+.1f} % |")
    shares = [r["share"] for r in rows]
    summed = sum(r["signature_s"] for r in rows) / sum(r["conversion_s"] for r in rows)
    ab = [r["ab_share"] for r in rows]
    print(f"\n{len(rows)} items at {resolution}³: signature share median "
          f"{100 * statistics.median(shares):.2f} %, p90 "
          f"{100 * sorted(shares)[int(0.9 * (len(shares) - 1))]:.2f} %, max "
          f"{100 * max(shares):.2f} %, summed {100 * summed:.2f} %; A/B share median "
          f"{100 * statistics.median(ab):+.2f} %")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("corpus", help="folder of meshes")
    ap.add_argument("--resolution", type=int, default=256)
    add_binary_argument(ap)
    add_record_argument(ap)
    ap.add_argument("--out", help="also write each row as a JSON line here")
    ap.add_argument("--every", type=int, default=1, help="every N-th mesh by name")
    ap.add_argument("--summarize", action="store_true",
                    help="only print the table of an existing --out file")
    args = ap.parse_args()
    if args.summarize:
        rows = [json.loads(l) for l in open(args.out) if l.strip()]
        print_table(rows, args.resolution)
        return
    paths = sorted(os.path.join(args.corpus, f) for f in os.listdir(args.corpus)
                   if os.path.splitext(f)[1].lower() in MESH_EXTENSIONS)[::args.every]
    sparc3d = binary(args.bin)
    results = Results("signature_cost", args.record, sparc3d)
    rows = []
    out = open(args.out, "w") if args.out else None
    with tempfile.TemporaryDirectory() as scratch:
        for n, path in enumerate(paths):
            row = measure(sparc3d, path, args.resolution, n % 2 == 1, scratch)
            if row is None:
                continue
            rows.append(row)
            results.add({"resolution": args.resolution, **row})
            if out:
                out.write(json.dumps(row) + "\n")
                out.flush()
    if rows:
        print_table(rows, args.resolution)


if __name__ == "__main__":
    main()
