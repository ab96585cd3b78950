"""Vector-set samples and the exports of other codebases' layouts, end to end: a job with
`[samples]`, its sample columns through the reader, every `sparc3d export` format loaded with
numpy alone (the snippet of docs/FORMAT.md, as printed there) and with the reader's collate
functions, and the errors for bad requests."""

import re
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest

from sparc3d_cli import ROOT, run, sparc3d_bin

try:
    import sparc3d_reader as reader
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

COUNTS = {"surface": 300, "sharp": 200, "near": 400, "sharp_near": 250, "volume": 500}


def snippet(name):
    text = (ROOT / "docs" / "FORMAT.md").read_text()
    m = re.search(r"<!-- snippet:%s.*?-->\s*```python\n(.*?)```" % name, text, re.S)
    assert m, "docs/FORMAT.md has no %s snippet" % name
    return m.group(1)


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("samples")
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in ["sphere.obj", "cube.off", "wuson.stl"]:
        (meshes / name).write_bytes((ROOT / "examples" / name).read_bytes())
    (meshes / "empty.obj").write_text("v 0 0 0\nv 1 0 0\n")
    manifest = tmp / "m.jsonl"
    run("manifest", "build", meshes, "-o", manifest)
    config = tmp / "job.toml"
    config.write_text("[samples]\nenabled = true\n" + "".join(
        "%s = %d\n" % kv for kv in COUNTS.items()) + 'dtype = "f16"\nseed = 7\n')
    path = tmp / "job"
    run("init", path, "--manifest", manifest, "--resolution", "48", "--config", config)
    run("run", path, "--workers", "1")
    return path


def ok_rows(job):
    rows = pq.read_table(job / "shards" / "part-00000.parquet").to_pylist()
    return [r for r in rows if r["status"] == "ok"], rows


def test_sample_columns_hold_the_configured_counts_in_f16(job):
    ok, rows = ok_rows(job)
    assert len(ok) == 3
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(failed) == 1 and failed[0]["error_class"] == "empty_mesh"
    for r in ok:
        for name in reader.SAMPLE_TENSORS:  # framed like every blob: zstd, content checksum
            assert r[name][:4] == b"\x28\xb5\x2f\xfd" and r[name][4] & 0x04, name
    items = list(reader.iter_items(job))
    for it in items:
        s = it["samples"]
        assert s["surface_points"].shape == (COUNTS["surface"], 3)
        assert s["surface_points"].dtype == np.float16
        assert s["near_sdf"].shape == (COUNTS["near"],)
        assert s["volume_occupancy"].dtype == np.uint8
        np.testing.assert_array_equal(s["volume_occupancy"] == 1, s["volume_sdf"] < 0)
        assert np.all(np.abs(s["volume_points"]) <= 1.05)
        # Surface normals are unit vectors (up to f16 rounding).
        lengths = np.linalg.norm(s["surface_normals"].astype(np.float32), axis=1)
        assert np.all(np.abs(lengths - 1) < 2e-3)
        # Near points lie near the surface: most within a few sigma (0.05 at most).
        assert np.median(np.abs(s["near_sdf"].astype(np.float32))) < 0.05
        assert len(s["sharp_points"]) in (0, COUNTS["sharp"])
        assert len(s["sharp_near_points"]) in (0, COUNTS["sharp_near"])
        assert s["sharp_near_sdf"].shape == (len(s["sharp_near_points"]),)
    cube = next(it for it in items if it["uri"].endswith("cube.off"))
    assert len(cube["samples"]["sharp_points"]) == COUNTS["sharp"]
    # Sharp-near points straddle the cube's edges: both sides, close to the surface.
    sharp_near_sdf = cube["samples"]["sharp_near_sdf"].astype(np.float32)
    assert len(sharp_near_sdf) == COUNTS["sharp_near"]
    assert (sharp_near_sdf < 0).any() and (sharp_near_sdf > 0).any()
    assert np.median(np.abs(sharp_near_sdf)) < 0.05
    # Inside points of the unit cube: the volume occupancy matches the cube in the source frame.
    src = reader.samples_to_source(cube)
    inside = np.all(np.abs(src["volume_points"]) < 0.5, axis=1)  # cube.off spans [-0.5, 0.5]^3
    margin = np.abs(src["volume_sdf"]) > 0.02
    agree = (inside == (src["volume_occupancy"] == 1))[margin]
    assert agree.mean() > 0.99
    batch = reader.collate_vecset(items)
    assert batch["surface"].shape == (3, COUNTS["surface"], 6)
    assert batch["volume_sdf"].shape == (3, COUNTS["volume"])


def test_every_export_loads_with_numpy_alone_and_with_the_reader(job, tmp_path):
    ok, rows = ok_rows(job)
    for fmt in reader.EXPORT_FORMATS:
        out = tmp_path / fmt
        # direct3d-s2's own frame needs a job with object_span = 0.95; this one is written in
        # the job's frame (tests/python/test_grid_exports.py exports its frame).
        frame = "normalized" if fmt == "direct3d-s2" else None
        reader.run_export(job, fmt, out, frame=frame, binary=sparc3d_bin())
        files = sorted(out.glob("*.npz"))
        assert len(files) == len(ok), fmt
        scope = {"path": str(files[0]), "fmt": fmt}
        exec(snippet("read-export"), scope)
        assert scope["center"].shape == (3,) and scope["scale"] > 0
        assert scope["item_id"] == rows[scope["item_index"]]["id"]  # one shard: rows[i] is item i
        items = list(reader.iter_export(out))
        if fmt == "vecset-npz":
            b = reader.collate_vecset(items)
            assert b["near_points"].shape == (len(ok), COUNTS["near"], 3)
            assert "sharp_near_points" in b and "sharp_near_sdf" in b
        elif fmt == "direct3d-s2":
            b = reader.collate_direct3d_s2(items)
            assert b["coords"].dtype == np.int32 and b["coords"].shape[1] == 4
            assert np.all(np.abs(b["sparse_sdf"]) < 1)
            assert b["batch_idx"].max() == len(ok) - 1
        else:
            b = reader.collate_cubvh(items)
            assert b["corners"].shape == (len(b["coords"]), 8)
            # Every active cell has corners of both signs (the sign bit: a tiny negative
            # value decodes to -0.0, as in cubvh's own dequantize).
            inside = (b["codes"] & 0x80) != 0
            assert np.all(inside.any(1) & ~inside.all(1))
            np.testing.assert_array_equal(np.signbit(b["corners"]), inside)


def test_frames_and_ids(job, tmp_path):
    ok, _ = ok_rows(job)
    one = ok[0]["id"]
    src = reader.run_export(job, "vecset-npz", tmp_path / "s", ids=[one], frame="source",
                            binary=sparc3d_bin())
    # The default frame of vecset-npz is the job's normalized frame, where our VAE trains.
    nrm = reader.run_export(job, "vecset-npz", tmp_path / "n", ids=[one], binary=sparc3d_bin())
    (a,), (b,) = list(reader.iter_export(src)), list(reader.iter_export(nrm))
    assert str(a["frame"]) == "source" and str(b["frame"]) == "normalized"
    assert b["near_points"].dtype == np.float16 and a["near_points"].dtype == np.float32
    scale, center = float(a["scale"]), a["center"]
    np.testing.assert_allclose(a["volume_points"], b["volume_points"].astype(np.float64) / (2 * scale) + center,
                               rtol=1e-5, atol=1e-5 / scale)
    np.testing.assert_allclose(a["near_sdf"], b["near_sdf"].astype(np.float64) / (2 * scale), rtol=1e-5, atol=1e-9)
    item = next(it for it in reader.iter_items(job) if it["id"] == one)
    np.testing.assert_array_equal(item["samples"]["near_points"], b["near_points"])


def test_bad_requests_are_named(job, tmp_path):
    r = run("export", job, "--format", "obj", "--out", tmp_path / "x", check=False)
    assert r.returncode != 0 and "vecset-npz" in r.stderr
    r = run("export", job, "--format", "cubvh", "--out", tmp_path / "x", "--ids", "nope", check=False)
    assert r.returncode != 0 and "nope" in r.stderr
    # A job without samples asked for samples: the key is named.
    manifest = tmp_path / "m.jsonl"
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    (meshes / "cube.off").write_bytes((ROOT / "examples" / "cube.off").read_bytes())
    run("manifest", "build", meshes, "-o", manifest)
    plain = tmp_path / "plain"
    run("init", plain, "--manifest", manifest, "--resolution", "32")
    run("run", plain, "--workers", "1")
    r = run("export", plain, "--format", "vecset-npz", "--out", tmp_path / "y", check=False)
    assert r.returncode != 0 and "samples.enabled" in r.stderr
    # A sample count that would not fit in memory is refused at init, naming the key.
    big = tmp_path / "big.toml"
    big.write_text("[samples]\nenabled = true\nvolume = 100000000000\n")
    r = run("init", tmp_path / "big", "--manifest", manifest, "--config", big, check=False)
    assert r.returncode != 0 and "samples.volume" in r.stderr


def test_a_shard_without_the_sharp_near_columns_reads_as_before(job, tmp_path):
    # A shard written before the sharp-near kind existed has no such columns; its items read
    # with the other samples, and collate_vecset leaves the kind out.
    shard = job / "shards" / "part-00000.parquet"
    old = pq.read_table(shard).drop_columns(["%s%s" % (t, s) for t in reader.OPTIONAL_SAMPLE_TENSORS
                                            for s in ("", "_dtype", "_shape")])
    path = tmp_path / "old.parquet"
    # With the shard's key-value metadata (schema version, config).
    pq.write_table(old.replace_schema_metadata(pq.ParquetFile(shard).metadata.metadata), path)
    items = list(reader.iter_items(path))
    assert len(items) == 3
    for it in items:
        assert it["samples"]["near_sdf"].shape == (COUNTS["near"],)
        assert "sharp_near_points" not in it["samples"]
    assert "sharp_near_points" not in reader.collate_vecset(items)
