"""A job grown by `sparc3d add` reads as one job: the reader checks each shard's rows against
the shards its frozen manifest gives them (not `index // shard_size`, which a grown job's later
shards do not follow) and yields every item once, in item order."""

import shutil

from sparc3d_cli import ROOT, run
import sparc3d_reader


def test_a_grown_job_reads_as_one(tmp_path):
    first, later = tmp_path / "first", tmp_path / "later"
    first.mkdir()
    later.mkdir()
    for name in ["cube.off", "sphere.obj", "wuson.stl"]:
        shutil.copy(ROOT / "examples" / name, first / name)
    for name in ["box_textured.glb", "cube_binary.ply"]:
        shutil.copy(ROOT / "examples" / name, later / name)
    job = tmp_path / "job"
    run("run", first, "--job", job, "--resolution", 32, "--shard-size", 2, "--workers", 2)
    r = run("add", job, later)
    assert "added 2 new items as shards 2..2" in r.stderr
    run("run", job, "--workers", 2)

    items = list(sparc3d_reader.iter_items(str(job)))
    assert [i["item_index"] for i in items] == [0, 1, 2, 3, 4]
    assert [i["uri"].rsplit("/", 1)[1] for i in items] == [
        "cube.off", "sphere.obj", "wuson.stl", "box_textured.glb", "cube_binary.ply"]
    assert len(sparc3d_reader.shard_paths(str(job))) == 3
