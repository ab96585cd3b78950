#!/usr/bin/env python3
"""What single-bit flips in a shard's column chunks do to the Python reader
(docs/RELIABILITY.md, "The Python reader", "What a checksum covers").

Flips every bit of the column chunks of each group below in one shard file, one flip at a
time, reads the file with `sparc3d_reader.iter_items` under each `verify` mode and counts the
outcomes: an error, the shard left out with a ShardWarning, the same items as the clean file,
or other items (the failure the checks exist to prevent). The file is restored at the end.

    python3 ops/bench/reader_bit_flips.py JOB/shards/part-00000.parquet [--verify full,false]
"""

import argparse
import collections
import pathlib
import sys
import warnings

import numpy as np
import pyarrow.parquet as pq

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "python"))
import sparc3d_reader as reader  # noqa: E402

GROUPS = {
    "center_*, scale": lambda c: c in ("scale", "center_x", "center_y", "center_z"),
    "*_dtype, *_shape": lambda c: "_dtype" in c or "_shape" in c,
    "item_index, id, uri, status, resolution": lambda c: c in (
        "item_index", "id", "uri", "status", "resolution"),
}
MODES = {"full": True, "quick": "quick", "false": False}


def chunk_offsets(path, wanted):
    rg = pq.ParquetFile(path).metadata.row_group(0)
    out = []
    for i in range(rg.num_columns):
        c = rg.column(i)
        if wanted(c.path_in_schema):
            start = c.dictionary_page_offset or c.data_page_offset
            out.extend(range(start, start + c.total_compressed_size))
    return out


def items(path, verify):
    return [{k: v for k, v in it.items() if k != "samples"}
            for it in reader.iter_items(path, verify=verify)]


def same(a, b):
    if len(a) != len(b):
        return False
    for x, y in zip(a, b):
        if x.keys() != y.keys():
            return False
        for k in x:
            if isinstance(y[k], np.ndarray):
                if x[k].shape != y[k].shape or not np.array_equal(x[k], y[k]):
                    return False
            elif x[k] != y[k]:
                return False
    return True


def outcome(path, verify, want):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            got = items(path, verify)
        except Exception:
            return "error"
    if same(got, want):
        return "same items"
    if not got and any(issubclass(w.category, reader.ShardWarning) for w in caught):
        return "left out"
    return "OTHER ITEMS"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("shard", type=pathlib.Path)
    ap.add_argument("--verify", default="full,false", help="modes: full, quick, false")
    args = ap.parse_args()
    clean = args.shard.read_bytes()
    want = items(args.shard, True)
    try:
        for label, wanted in GROUPS.items():
            offsets = chunk_offsets(args.shard, wanted)
            for mode in args.verify.split(","):
                counts = collections.Counter()
                for offset in offsets:
                    for bit in range(8):
                        data = bytearray(clean)
                        data[offset] ^= 1 << bit
                        args.shard.write_bytes(bytes(data))
                        counts[outcome(args.shard, MODES[mode], want)] += 1
                print(f"{label}: {len(offsets) * 8} flips in {len(offsets)} bytes, "
                      f"verify={mode}: {dict(counts)}", flush=True)
    finally:
        args.shard.write_bytes(clean)


if __name__ == "__main__":
    main()
