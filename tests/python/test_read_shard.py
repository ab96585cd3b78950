"""Reads a shard written by the CLI with pyarrow + numpy, using the snippet of docs/FORMAT.md
exactly as printed there, and checks the tensors against the CLI's own decode
(`sparc3d show --tensors-json`)."""

import json
import re

import numpy as np
import pyarrow.parquet as pq

from sparc3d_cli import ROOT, run


def snippet():
    text = (ROOT / "docs" / "FORMAT.md").read_text()
    m = re.search(r"<!-- snippet:read-shard.*?-->\s*```python\n(.*?)```", text, re.S)
    assert m, "docs/FORMAT.md has no read-shard snippet"
    return m.group(1)


def test_snippet_reads_what_the_cli_decodes(tmp_path):
    manifest = tmp_path / "m.jsonl"
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for name in ["sphere.obj", "cube.off"]:
        (meshes / name).write_bytes((ROOT / "examples" / name).read_bytes())
    (meshes / "broken.obj").write_text("not a mesh\n")
    run("manifest", "build", str(meshes), "-o", str(manifest))
    job = tmp_path / "job"
    run("init", str(job), "--manifest", str(manifest), "--resolution", "40")
    run("run", str(job), "--workers", "1")

    path = str(job / "shards" / "part-00000.parquet")
    scope = {"path": path}
    exec(snippet(), scope)
    row = scope["row"]
    assert scope["coords"].dtype == np.uint16 and scope["coords"].shape[1] == 3
    assert scope["sdf"].shape == (scope["coords"].shape[0],)

    meta = pq.read_metadata(path).metadata
    assert meta[b"sparc3d.schema_version"] == b"3"
    assert any(r["status"] == "failed" for r in scope["rows"])

    for r in scope["rows"]:
        if r["status"] != "ok":
            assert scope["tensor"](r, "coords") is None
            continue
        out = tmp_path / f"{r['item_index']}.json"
        run("show", str(job), "--id", r["id"], "-o", str(tmp_path / "m.ply"),
            "--tensors-json", str(out))
        cli = json.loads(out.read_text())
        t = scope["tensor"]
        np.testing.assert_array_equal(t(r, "coords"), np.array(cli["coords"], dtype=np.uint16))
        np.testing.assert_array_equal(t(r, "cells"), np.array(cli["cells"], dtype=np.uint16).reshape(-1, 3))
        np.testing.assert_array_equal(t(r, "sdf"), np.array(cli["sdf"], dtype=np.float32))
        np.testing.assert_array_equal(
            t(r, "deformation"), np.array(cli["deformation"], dtype=np.float32).reshape(-1, 3))
        assert r["active_vertices"] == len(cli["coords"])
        assert r["resolution"] == cli["resolution"] == 40
