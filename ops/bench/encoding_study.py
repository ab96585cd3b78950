#!/usr/bin/env python3
"""Stored size of the sparse cube tensors under candidate encodings (docs/PERFORMANCE.md).

Reads every ok row of a job's shards with the project's reader and measures, per tensor,
the zstd-compressed bytes per active vertex of:

* `raw`      — the elements' little-endian bytes row-major, one zstd frame (schema
               version 1);
* `planes`   — the same bytes regrouped column by column and byte plane by byte plane
               (all x low bytes, all x high bytes, all y low bytes, ...): lossless; the
               stored encoding since schema version 2 (docs/FORMAT.md);
* `delta`    — (coords, cells) differences of consecutive rows, column by column, then byte
               planes: lossless for sorted coordinates;
* `f16`      — (sdf) half precision, byte planes: lossy, the maximum error is printed;
* `derived`  — (cells) nothing stored: the cells are the cells with a sign change among
               their eight corners, all of them active vertices (`SparseCubes` invariant),
               so a reader can recompute them from coords and sdf.

zstd runs through pyarrow's codec at the job's level (`--level`, 3 by default) and the time
each candidate takes to compress is summed, so size and speed are compared in one run.

    python3 ops/bench/encoding_study.py JOB [--level 3] [--limit N] [--json]
"""

import argparse
import json
import os
import sys
import time

import numpy as np
import pyarrow as pa

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "python"))
from sparc3d_reader import iter_items  # noqa: E402


def planes(a):
    """The bytes of `a` (C order [n, k] or [n]) regrouped by column, then by byte plane."""
    a = np.ascontiguousarray(a)
    cols = a.reshape(len(a), -1).T  # [k, n]
    width = a.dtype.itemsize
    b = np.ascontiguousarray(cols).view(np.uint8).reshape(cols.shape[0], cols.shape[1], width)
    return np.ascontiguousarray(b.transpose(0, 2, 1)).tobytes()


def delta(a):
    """Differences of consecutive rows (first row kept), wrapping in the same dtype."""
    a = np.ascontiguousarray(a)
    d = a.copy()
    d[1:] = a[1:] - a[:-1]
    return d


def derived_cells(coords, sdf):
    """The cells with a sign change among eight active corners, sorted like the stored ones."""
    keys = (coords[:, 0].astype(np.int64) << 32) | (coords[:, 1].astype(np.int64) << 16) | coords[:, 2]
    order = np.argsort(keys)
    keys, inside = keys[order], (sdf < 0)[order]
    cand = coords[order]
    n_in = np.zeros(len(cand), np.int8)
    ok = np.ones(len(cand), bool)
    for d in range(8):
        off = np.array([d & 1, (d >> 1) & 1, d >> 2], np.int64)
        k = ((cand[:, 0] + off[0]) << 32) | ((cand[:, 1] + off[1]) << 16) | (cand[:, 2] + off[2])
        pos = np.searchsorted(keys, k)
        pos = np.minimum(pos, len(keys) - 1)
        found = keys[pos] == k
        ok &= found
        n_in += (found & inside[pos]).astype(np.int8)
    keep = ok & (n_in > 0) & (n_in < 8)
    return cand[keep]


class Meter:
    """Compressed bytes and seconds per (tensor, candidate)."""

    def __init__(self, level):
        self.codec = pa.Codec("zstd", compression_level=level)
        self.bytes = {}
        self.seconds = {}

    def add(self, key, data):
        t0 = time.perf_counter()
        size = len(self.codec.compress(data, asbytes=True))
        self.seconds[key] = self.seconds.get(key, 0.0) + time.perf_counter() - t0
        self.bytes[key] = self.bytes.get(key, 0) + size


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("job", help="job folder (or shard files) written by sparc3d")
    p.add_argument("--level", type=int, default=3, help="zstd level (the job default is 3)")
    p.add_argument("--limit", type=int, default=0, help="stop after this many items (0: all)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args()

    m = Meter(args.level)
    vertices = items = 0
    sdf_err = 0.0
    cells_match = True
    for item in iter_items(args.job):
        if args.limit and items >= args.limit:
            break
        coords = item["coords"].astype(np.uint16)
        sdf = item["sdf"].astype(np.float32)
        deformation = item["deformation"].astype(np.float32)
        cells = item["cells"].astype(np.uint16)
        items += 1
        vertices += len(coords)
        for name, a in (("coords", coords), ("sdf", sdf), ("deformation", deformation), ("cells", cells)):
            m.add((name, "raw"), a.tobytes())
            m.add((name, "planes"), planes(a))
        for name, a in (("coords", coords), ("cells", cells)):
            m.add((name, "delta"), planes(delta(a)))
        half = sdf.astype(np.float16)
        sdf_err = max(sdf_err, float(np.max(np.abs(half.astype(np.float32) - sdf))) if len(sdf) else 0.0)
        m.add(("sdf", "f16"), planes(half))
        m.bytes[("cells", "derived")] = 0
        m.seconds[("cells", "derived")] = 0.0
        if cells_match and items <= 20:
            cells_match = np.array_equal(derived_cells(coords.astype(np.int64), sdf), cells.astype(np.int64))

    if not vertices:
        print("no ok rows with tensors in %s" % args.job, file=sys.stderr)
        return 2
    per = {"%s/%s" % k: v / vertices for k, v in m.bytes.items()}
    secs = {"%s/%s" % k: v for k, v in m.seconds.items()}
    report = {"items": items, "active_vertices": vertices, "zstd_level": args.level,
              "bytes_per_active_vertex": per, "compress_seconds": secs,
              "f16_sdf_max_abs_error_voxels": sdf_err,
              "cells_derivable_checked_on_first_20": cells_match}
    if args.json:
        print(json.dumps(report, indent=1))
        return 0
    print("%d items, %d active vertices, zstd level %d" % (items, vertices, args.level))
    print("%-12s %-9s %10s %12s" % ("tensor", "encoding", "B/vertex", "compress s"))
    for (name, enc), b in sorted(m.bytes.items()):
        print("%-12s %-9s %10.3f %12.2f" % (name, enc, b / vertices, m.seconds[(name, enc)]))
    print("f16 sdf: max |error| %.2e voxel; cells derivable from coords+sdf (first 20 items): %s"
          % (sdf_err, cells_match))
    return 0


if __name__ == "__main__":
    sys.exit(main())
