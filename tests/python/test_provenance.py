"""Provenance columns (docs/FORMAT.md, "Provenance columns"): a manifest's own columns come
through a job as `manifest.<name>` string columns that pyarrow reads as columns, and the reader
gives them as `item["manifest"]`."""

import pyarrow.compute as pc
import pyarrow.dataset as ds
import shutil

from sparc3d_cli import ROOT, run
import sparc3d_reader


def test_provenance_columns_read_as_columns(tmp_path):
    meshes = tmp_path / "meshes"
    meshes.mkdir()
    for name in ["cube.off", "sphere.obj", "wuson.stl"]:
        shutil.copy(ROOT / "examples" / name, meshes / name)
    (tmp_path / "m.csv").write_text(
        "path,license,caption\n"
        "meshes/cube.off,cc0,a cube\n"
        "meshes/sphere.obj,cc-by,\n"
        "meshes/wuson.stl,by-nc,a duck\n")
    job = tmp_path / "job"
    r = run("run", tmp_path / "m.csv", "--job", job, "--where", "license != by-nc",
            "--resolution", 32, "--shard-size", 1, "--workers", 2)
    assert "2 rows kept, 1 left out" in r.stderr

    shards = sorted(str(p) for p in (job / "shards").glob("*.parquet"))
    table = ds.dataset(shards, format="parquet").to_table(
        columns=["item_index", "manifest.license", "manifest.caption"])
    table = table.sort_by("item_index")
    assert table.column("manifest.license").to_pylist() == ["cc0", "cc-by"]
    assert table.column("manifest.caption").to_pylist() == ["a cube", None]
    cc0 = table.filter(pc.field("manifest.license") == "cc0")
    assert cc0.num_rows == 1

    items = sorted(sparc3d_reader.iter_items(str(job)), key=lambda i: i["item_index"])
    assert [i["manifest"] for i in items] == [
        {"license": "cc0", "caption": "a cube"}, {"license": "cc-by", "caption": None}]
