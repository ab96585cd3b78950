"""A damaged tensor blob fails loudly in every zstd decoder (issue 10, item 2): schema version 3
stores zstd's content checksum in every frame, so pyarrow's `pa.decompress` (the snippet of
docs/FORMAT.md) and the Python reader refuse a blob with a flipped byte instead of returning
wrong numbers."""

import shutil
import sys

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sparc3d_cli import ROOT, run
try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader


@pytest.fixture(scope="module")
def row(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("damaged")
    meshes = tmp / "meshes"
    meshes.mkdir()
    shutil.copy(ROOT / "examples" / "sphere.obj", meshes / "sphere.obj")
    run("manifest", "build", meshes, "-o", tmp / "m.jsonl")
    job = tmp / "job"
    run("init", job, "--manifest", tmp / "m.jsonl", "--resolution", 48)
    run("run", job, "--workers", 1)
    rows = pq.read_table(job / "shards" / "part-00000.parquet").to_pylist()
    return next(r for r in rows if r["status"] == "ok")


def flipped(blob, at, bit=0x10):
    b = bytearray(blob)
    b[at] ^= bit
    return bytes(b)


def test_every_blob_carries_a_checksum(row):
    for name in reader.TENSORS:
        blob = row[name]
        assert blob[:4] == b"\x28\xb5\x2f\xfd", name  # a zstd frame
        assert blob[4] & 0x04, f"{name}: no content checksum flag"


def test_pyarrow_and_the_reader_refuse_a_flipped_byte(row):
    good = reader.decode_tensor(row, "sdf")
    blob = row["sdf"]
    n, size = len(good), good.dtype.itemsize
    refused = 0
    places = range(8, len(blob), max(1, len(blob) // 40))
    for at in places:
        bad = dict(row, sdf=flipped(blob, at))
        try:
            pa.decompress(bad["sdf"], decompressed_size=n * size, codec="zstd")
        except (OSError, pa.ArrowException):
            refused += 1
        else:
            # Only a bit zstd does not use may pass, and then the numbers are the same.
            np.testing.assert_array_equal(reader.decode_tensor(bad, "sdf"), good)
            continue
        with pytest.raises((OSError, pa.ArrowException)):
            reader.decode_tensor(bad, "sdf")
    assert refused >= len(places) - 1, f"{refused} of {len(places)} flips refused"

