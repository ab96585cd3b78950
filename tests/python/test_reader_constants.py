"""The reader's copies of the binary's constants (python/sparc3d_reader/schema.py) against what
`sparc3d` writes and prints: a job it converts here (the shard's footer keys, schema version,
columns, tensor stems in column order, statuses, provenance prefix, the sample kinds a job may
leave null) and its own output (`inspect --json`, `show --tensors-json`, `export --help`).
A constant changed on one side only fails here, naming what differs."""

import json
import re
import shutil

import numpy as np
import pyarrow.parquet as pq
import pytest

from sparc3d_cli import ROOT, run
import sparc3d_reader
from sparc3d_reader import schema

#: A small sample config that draws every kind but the sharp-near one, so that its columns
#: are null as in every job that draws none of it.
SAMPLES = """[samples]
enabled = true
surface = 32
sharp = 8
near = 32
volume = 32
sharp_near = 0
"""


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    """Two meshes and a file that is not one (a failed row), with samples and a provenance
    column, converted at 32³ into one shard."""
    tmp = tmp_path_factory.mktemp("constants")
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in ["cube.off", "sphere.obj"]:
        shutil.copy(ROOT / "examples" / name, meshes / name)
    (meshes / "broken.obj").write_text("not a mesh\n")
    (tmp / "m.csv").write_text("path,license\nmeshes/cube.off,cc0\nmeshes/sphere.obj,cc-by\n"
                               "meshes/broken.obj,cc0\n")
    (tmp / "job.toml").write_text(SAMPLES)
    job = tmp / "job"
    run("run", tmp / "m.csv", "--job", job, "--config", tmp / "job.toml", "--resolution", 32,
        "--workers", 1)
    return job


@pytest.fixture(scope="module")
def shard(job):
    return job / "shards" / "part-00000.parquet"


@pytest.fixture(scope="module")
def rows(shard):
    return pq.read_table(shard).to_pylist()


def stems(columns):
    """The tensor stems among column names, in order: names with `_dtype` and `_shape` beside."""
    names = set(columns)
    return [c for c in columns if f"{c}_dtype" in names and f"{c}_shape" in names]


def test_schema_version_and_footer_keys(job, shard):
    meta = pq.ParquetFile(shard).metadata.metadata
    assert meta[schema.META_SCHEMA_VERSION.encode()] == str(schema.SCHEMA_VERSION).encode()
    record = json.loads(shard.with_name("part-00000.complete.json").read_text())
    assert meta[schema.META_FINGERPRINT.encode()].decode() == record["fingerprint"]
    assert sparc3d_reader.shard_config(shard), f"no config under {schema.META_CONFIG!r}"
    inspect = json.loads(run("inspect", job, "--json").stdout)
    assert inspect["schema_versions"] == [str(schema.SCHEMA_VERSION)]
    sparc3d_reader.check_schema_version(shard)


def test_tensor_stems_in_column_order(job, shard):
    """Every tensor the shard holds is one the reader decodes or knows it leaves, in the order
    the binary writes them (the cube tensors, the mesh, then the samples)."""
    columns = pq.ParquetFile(shard).schema_arrow.names
    assert stems(columns) == [*schema.TENSORS, *schema.UNREAD_TENSORS, *schema.SAMPLE_TENSORS]
    column_bytes = json.loads(run("inspect", job, "--json").stdout)["column_bytes"]
    listed = [c.split(".")[0] for c in column_bytes]  # `coords_shape.list.item` → `coords_shape`
    assert set(stems(listed)) == {*schema.TENSORS, *schema.UNREAD_TENSORS, *schema.SAMPLE_TENSORS}


def test_metadata_and_provenance_columns(shard):
    columns = pq.ParquetFile(shard).schema_arrow.names
    missing = [c for c in schema.META_COLUMNS if c not in columns]
    assert not missing, f"META_COLUMNS not in a fresh shard: {missing}"
    assert [c for c in columns if c.startswith(schema.PROVENANCE_PREFIX)] == [
        f"{schema.PROVENANCE_PREFIX}license"]


def test_statuses(rows):
    seen = {r["status"] for r in rows}
    assert seen == {"ok", "failed"}  # what this job's rows are
    assert seen <= set(schema.STATUSES)


def test_stored_dtypes_fit_the_readers(rows):
    """The reader casts each cube tensor to its TENSORS dtype: every dtype the binary stores
    must cast to it without loss."""
    for r in (r for r in rows if r["status"] == "ok"):
        for name, dtype in schema.TENSORS.items():
            stored = np.dtype(r[f"{name}_dtype"])
            assert np.can_cast(stored, dtype, "safe"), (name, stored, dtype)


def test_optional_sample_kinds_are_the_null_ones_and_last(rows):
    """A job that draws no sharp-near samples leaves exactly OPTIONAL_SAMPLE_TENSORS null, and
    they come last (the columns of older shards keep their places)."""
    n = len(schema.OPTIONAL_SAMPLE_TENSORS)
    assert schema.SAMPLE_TENSORS[-n:] == schema.OPTIONAL_SAMPLE_TENSORS
    for r in (r for r in rows if r["status"] == "ok"):
        assert [t for t in schema.SAMPLE_TENSORS if r[t] is None] == schema.OPTIONAL_SAMPLE_TENSORS


def test_cube_tensors_are_the_ones_show_decodes(job, rows, tmp_path):
    item = next(r for r in rows if r["status"] == "ok")
    out = tmp_path / "tensors.json"
    run("show", job, "--id", item["id"], "-o", tmp_path / "x.ply", "--tensors-json", out)
    decoded = {k for k, v in json.loads(out.read_text()).items() if isinstance(v, list)}
    assert decoded - {"center"} == set(schema.TENSORS)


def test_export_formats_are_the_binarys():
    """EXPORT_FORMATS and CONSUMER_FORMATS together are `sparc3d export --format`'s values."""
    help_text = run("export", "--help").stdout
    values = re.findall(r"^\s+- ([a-z0-9][a-z0-9.-]*):", help_text, re.M)
    ours = list(schema.EXPORT_FORMATS) + list(schema.CONSUMER_FORMATS)
    assert values and len(set(ours)) == len(ours)
    assert sorted(ours) == sorted(values)


def test_quality_and_signature_columns_are_the_binarys_and_in_every_item(job, shard):
    """QUALITY_COLUMNS and then SHAPE_SIGNATURE_COLUMN are the columns a job with both (the
    default) writes between its tensors and its provenance columns, in order; every item holds
    them, and a failed row holds none (null)."""
    columns = pq.ParquetFile(shard).schema_arrow.names
    after_tensors = columns.index(schema.SAMPLE_TENSORS[-1] + "_shape") + 1
    first_provenance = next(i for i, c in enumerate(columns) if c.startswith(schema.PROVENANCE_PREFIX))
    signature = schema.SHAPE_SIGNATURE_COLUMN
    assert columns[after_tensors:first_provenance] == schema.QUALITY_COLUMNS + [signature]
    items = list(sparc3d_reader.iter_items(job, samples=False))
    assert items and all(set(schema.QUALITY_COLUMNS) <= set(item) for item in items)
    assert all(item[signature].dtype == np.float32 and item[signature].shape == (32,)
               for item in items)
    cube = next(i for i in items if i["uri"].endswith("cube.off"))
    assert cube["input_boundary_edges"] == 0 and cube["aspect"] == pytest.approx(1.0)
    failed = [r for r in pq.read_table(shard).to_pylist() if r["status"] == "failed"]
    assert failed and all(r[c] is None for r in failed for c in schema.QUALITY_COLUMNS)
    assert all(r[signature] is None for r in failed)
