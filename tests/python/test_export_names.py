"""`sparc3d export` gives every item a file of its own, in every format: ids that map to the
same readable stem (`chair/1`, `chair 1`, `chair_1`; `椅子`, `桌子`), ids of any length (the
248–251-byte ones whose temporary name used to exceed 255 bytes, and far longer ones), each
file naming its item inside (`id`, `item_index`), and a file of another item already in the
output folder is never overwritten silently (docs/FORMAT.md, "Exports")."""

import json
import os
import sys

import numpy as np
import pytest

from sparc3d_cli import ROOT, run

try:
    import sparc3d_reader as reader
except ImportError:  # not installed: use the checkout's copy
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
# Ids whose readable stems collide, then ids around and far beyond the file-name limit
# (in bytes: 248..252 ASCII, 300 ASCII, 100 three-byte characters, 2000 ASCII).
IDS = (["chair/1", "chair 1", "chair_1", "椅子", "桌子"]
       + ["L" * n for n in (248, 249, 250, 251, 252, 300)]
       + ["长" * 100, "x" * 2000])
NAME_MAX = 255


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("export-names")
    manifest = tmp / "m.jsonl"
    with open(manifest, "w", encoding="utf-8") as f:
        for i, item_id in enumerate(IDS):
            uri = ROOT / "examples" / MESHES[i % len(MESHES)]
            f.write(json.dumps({"id": item_id, "uri": str(uri)}, ensure_ascii=False) + "\n")
    config = tmp / "job.toml"
    config.write_text("[samples]\nenabled = true\nsurface = 64\nsharp = 16\nnear = 64\n"
                      "sharp_near = 16\nvolume = 64\n")
    path = tmp / "job"
    run("init", path, "--manifest", manifest, "--resolution", 32, "--shard-size", 5,
        "--config", config)
    run("run", path, "--workers", 2)
    return path


@pytest.mark.parametrize("fmt", reader.EXPORT_FORMATS)
def test_every_item_gets_its_own_file_naming_it_inside(job, tmp_path, fmt):
    out = tmp_path / fmt
    r = run("export", job, "--format", fmt, "--out", out)
    assert f"{len(IDS)} items written" in r.stderr, r.stderr
    files = sorted(os.listdir(out))
    assert len(files) == len(IDS), files  # no file shared, no temporary left behind
    assert all(f.endswith(".npz") and not f.startswith(".") for f in files), files
    # Unique also where a file system ignores case, and within the limit with room for the
    # temporary name (`.NAME.PID.tmp`).
    assert len({f.lower() for f in files}) == len(files)
    assert max(len(f.encode()) for f in files) + len(".." + "4294967295" + ".tmp") <= NAME_MAX
    found = {}
    for f in files:
        with np.load(out / f) as z:
            found[str(z["id"])] = (int(z["item_index"]), f)
    assert sorted(found) == sorted(IDS)
    for i, item_id in enumerate(IDS):
        index, name = found[item_id]
        assert index == i and name.startswith("%06d-" % i), (item_id[:20], name)
    # The readable stem of a short id is the documented one.
    assert found["chair/1"][1] == "000000-chair_1.npz"
    assert found["椅子"][1] == "000003-__.npz"
    # The reader takes the id from inside the file, in manifest order.
    assert [it["id"] for it in reader.iter_export(out)] == IDS
    assert reader.ExportDataset(out)[3]["id"] == "椅子"


def test_another_items_file_is_never_overwritten(job, tmp_path):
    out = tmp_path / "out"
    run("export", job, "--format", "cubvh", "--out", out)
    before = {f: (out / f).read_bytes() for f in os.listdir(out)}
    # Exporting the same job again replaces its own files: same names, same bytes.
    run("export", job, "--format", "cubvh", "--out", out)
    assert {f: (out / f).read_bytes() for f in os.listdir(out)} == before
    # Item 1's file put where item 2's goes (another job's export with other ids, say), and a
    # file that is no export at all: both stay as they are, each named, and the exit is 1.
    taken = sorted(before)
    (out / taken[2]).write_bytes(before[taken[1]])
    (out / taken[4]).write_bytes(b"my own notes")
    r = run("export", job, "--format", "cubvh", "--out", out, check=False)
    assert r.returncode == 1, r.stderr
    assert f"{len(IDS) - 2} items written" in r.stderr and "2 failed" in r.stderr, r.stderr
    assert taken[2] in r.stderr and "already holds item 'chair 1'" in r.stderr.replace('"', "'"), r.stderr
    assert taken[4] in r.stderr and "not an export" in r.stderr, r.stderr
    assert (out / taken[2]).read_bytes() == before[taken[1]]
    assert (out / taken[4]).read_bytes() == b"my own notes"
    assert sorted(os.listdir(out)) == taken  # no temporary left behind
