"""The Python reader (python/sparc3d_reader) on shards written by the CLI: every item's
tensors equal the CLI's own decode (`sparc3d show --tensors-json`) exactly, and the collate
function builds the batched sparse layout."""

import json
import os
import pathlib
import shutil
import sys

import numpy as np
import pytest

from sparc3d_cli import ROOT, run
try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    if os.environ.get("SPARC3D_CI") == "1":
        raise  # CI tests the package as pip installs it (./test.sh does)
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("reader")
    meshes = tmp / "meshes"
    meshes.mkdir()
    for name in MESHES:
        shutil.copy(ROOT / "examples" / name, meshes / name)
    (meshes / "broken.obj").write_text("not a mesh\n")
    run("manifest", "build", meshes, "-o", tmp / "m.jsonl")
    job = tmp / "job"
    run("init", job, "--manifest", tmp / "m.jsonl", "--resolution", 64, "--shard-size", 4)
    run("run", job, "--workers", 2)
    return job


def cli_tensors(job, item_id, tmp):
    out = tmp / f"{item_id}.json"
    run("show", job, "--id", item_id, "-o", tmp / "x.ply", "--tensors-json", out)
    return json.loads(out.read_text())


def test_items_equal_the_cli_decode(job, tmp_path):
    items = list(reader.iter_items(job))
    assert len(items) == len(MESHES)  # the broken file is a failed row, left out
    assert len(reader.shard_paths(job)) == 2
    for it in items:
        cli = cli_tensors(job, it["id"], tmp_path)
        assert it["coords"].dtype == np.int32 and it["coords"].shape[1] == 3
        assert it["cells"].dtype == np.int32 and it["cells"].shape[1] == 3
        assert it["sdf"].dtype == np.float32 and it["sdf"].shape == (len(it["coords"]),)
        assert it["deformation"].dtype == np.float32 and it["deformation"].shape == it["coords"].shape
        np.testing.assert_array_equal(it["coords"], np.array(cli["coords"], dtype=np.int32).reshape(-1, 3))
        np.testing.assert_array_equal(it["cells"], np.array(cli["cells"], dtype=np.int32).reshape(-1, 3))
        np.testing.assert_array_equal(it["sdf"], np.array(cli["sdf"], dtype=np.float32))
        np.testing.assert_array_equal(
            it["deformation"], np.array(cli["deformation"], dtype=np.float32).reshape(-1, 3))
        assert it["resolution"] == cli["resolution"] == 64
        np.testing.assert_array_equal(it["center"], np.array(cli["center"]))
        assert it["scale"] == cli["scale"]
        assert pathlib.Path(it["uri"]).name in MESHES


def test_shard_files_and_incomplete_shards(job, tmp_path):
    shard = job / "shards" / "part-00000.parquet"
    assert len(list(reader.iter_items(shard))) == len(list(reader.iter_items([shard])))
    # A shard without its completion record is skipped in a job folder (it may be stale).
    copy = tmp_path / "job"
    shutil.copytree(job, copy)
    (copy / "shards" / "part-00001.complete.json").unlink()
    with pytest.warns(reader.ShardWarning, match="part-00001.parquet: not finished"):
        assert len(reader.shard_paths(copy)) == 1
    assert len(reader.shard_paths(copy, complete_only=False)) == 2
    with pytest.raises(FileNotFoundError):
        reader.shard_paths(tmp_path / "nothing")


def test_dataset_indexes_the_same_items(job):
    ds = reader.SparseCubesDataset(job)
    items = list(reader.iter_items(job))
    assert len(ds) == len(items)
    for i in [0, len(ds) - 1, 1, -1]:
        a, b = ds[i], items[i]
        assert a["id"] == b["id"]
        for name in reader.TENSORS:
            np.testing.assert_array_equal(a[name], b[name])
    with pytest.raises(IndexError):
        ds[len(ds)]
    assert [x["id"] for x in ds] == [x["id"] for x in items]
    tagged = reader.SparseCubesDataset(job, transform=lambda it: {**it, "tag": 1})
    assert tagged[0]["tag"] == 1


def test_collate_builds_batched_sparse_coordinates(job):
    items = list(reader.iter_items(job))[:3]
    batch = reader.collate_sparse(items)
    ks = [len(it["coords"]) for it in items]
    assert batch["coords"].dtype == np.int32 and batch["coords"].shape == (sum(ks), 4)
    assert batch["feats"].dtype == np.float32 and batch["feats"].shape == (sum(ks), 4)
    assert batch["offsets"].tolist() == [0, ks[0], ks[0] + ks[1], sum(ks)]
    assert batch["cells"].shape == (sum(len(it["cells"]) for it in items), 4)
    assert batch["ids"] == [it["id"] for it in items]
    for b, it in enumerate(items):
        lo, hi = batch["offsets"][b], batch["offsets"][b + 1]
        assert (batch["coords"][lo:hi, 0] == b).all()
        np.testing.assert_array_equal(batch["coords"][lo:hi, 1:], it["coords"])
        np.testing.assert_array_equal(batch["feats"][lo:hi, 0], it["sdf"])
        np.testing.assert_array_equal(batch["feats"][lo:hi, 1:], it["deformation"])
        clo, chi = batch["cell_offsets"][b], batch["cell_offsets"][b + 1]
        assert (batch["cells"][clo:chi, 0] == b).all()
        # corners: the rows of each cell's 8 corners, in CORNER_OFFSETS order.
        corners = batch["corners"][clo:chi]
        assert corners.dtype == np.int64 and corners.shape == (chi - clo, 8)
        assert ((corners >= lo) & (corners < hi)).all()
        expect = it["cells"][:, None, :] + reader.CORNER_OFFSETS[None, :, :]
        np.testing.assert_array_equal(batch["coords"][corners][..., 1:], expect)


def test_corner_index_refuses_a_missing_corner(job):
    it = next(reader.iter_items(job))
    cells = np.concatenate([it["cells"], [[9999, 0, 0]]]).astype(np.int32)
    with pytest.raises(ValueError, match="corner"):
        reader.corner_index(it["coords"], cells, it["id"])


def test_tensor_files_round_trip_and_extract_like_the_shard(job, tmp_path):
    """A tensor file written by the reader holds the same tensors, and `sparc3d extract`
    makes the same mesh from it as `sparc3d show` from the job."""
    it = next(reader.iter_items(job))
    row = {"id": it["id"], "resolution": it["resolution"], "center_x": float(it["center"][0]),
           "center_y": float(it["center"][1]), "center_z": float(it["center"][2]),
           "scale": it["scale"], "coords": it["coords"].astype(np.uint16), "sdf": it["sdf"],
           "deformation": it["deformation"], "cells": it["cells"].astype(np.uint16)}
    import pyarrow as pa

    path = tmp_path / "cubes.parquet"
    reader.write_tensor_file(path, [row], ["coords", "sdf", "deformation", "cells"],
                             schema={"resolution": pa.uint32()})
    back = list(reader.iter_tensor_rows(path, ["coords", "sdf", "deformation", "cells"]))
    assert len(back) == 1 and back[0]["id"] == it["id"]
    for name in ("coords", "sdf", "deformation", "cells"):
        np.testing.assert_array_equal(back[0][name], row[name])
        assert back[0][name].dtype == row[name].dtype
    run("extract", path, "-o", tmp_path / "from_file.ply")
    run("show", job, "--id", it["id"], "-o", tmp_path / "from_job.ply")
    assert (tmp_path / "from_file.ply").read_bytes() == (tmp_path / "from_job.ply").read_bytes()
    # A shard is a tensor file too; with several rows, --id is needed.
    shard = reader.shard_paths(job)[0]
    r = run("extract", shard, "-o", tmp_path / "x.ply", check=False)
    assert r.returncode != 0 and "--id" in r.stderr, r.stderr
    run("extract", shard, "--id", it["id"], "-o", tmp_path / "from_shard.ply")
    assert (tmp_path / "from_shard.ply").read_bytes() == (tmp_path / "from_job.ply").read_bytes()


def test_torch_dataset_and_loader(job):
    torch = pytest.importorskip("torch")
    ds = reader.SparseCubesDataset(job)
    assert isinstance(ds, torch.utils.data.Dataset)
    loader = torch.utils.data.DataLoader(
        ds, batch_size=2, collate_fn=lambda b: reader.collate_sparse(b, to_torch=True))
    batch = next(iter(loader))
    assert batch["coords"].dtype == torch.int32 and batch["coords"].shape[1] == 4
    assert batch["feats"].dtype == torch.float32
    assert int(batch["offsets"][-1]) == batch["coords"].shape[0]


def test_other_schema_versions_are_refused(job, tmp_path):
    """A shard whose footer names another schema version (v1 stored row-major bytes) is refused
    by the reader and by the CLI, naming both versions, instead of decoding garbage."""
    import pyarrow.parquet as pq

    src = reader.shard_paths(job)[0]
    table = pq.read_table(src)
    meta = dict(pq.ParquetFile(src).metadata.metadata)
    meta[b"sparc3d.schema_version"] = b"1"
    old = tmp_path / "part-00000.parquet"
    pq.write_table(table.replace_schema_metadata(meta), old)
    with pytest.raises(ValueError, match="schema version 1.*version 3"):
        list(reader.iter_items([old], complete_only=False))
    r = run("inspect", old, check=False)
    assert r.returncode != 0 and "schema version 1" in r.stderr, r.stderr
