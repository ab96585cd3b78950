"""The job the streaming and filter tests read: the example meshes over and over with
provenance columns, one file that is not a mesh (a failed row), in small shards, converted by
`sparc3d`; and the facts of each item the filters are checked against, computed from the files
and the manifest here rather than read from the shards."""

import json
import struct

from sparc3d_cli import ROOT, run

MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
ITEMS = 23  # ok items it00..it22, mesh i % 5; shard size 4: six shards of items + the broken one
IDS = ["it%02d" % i for i in range(ITEMS)]
LICENSES = ["cc0", "cc-by", "by-nc"]


def caption(i):
    """Every fourth item has a caption; the others none (null in the shards)."""
    return "a thing" if i % 4 == 0 else None


def manifest_rows():
    rows = []
    for i in range(ITEMS):
        row = {"id": IDS[i], "uri": str(ROOT / "examples" / MESHES[i % 5]),
               "license": LICENSES[i % 3], "year": str(2000 + i)}
        if caption(i):
            row["caption"] = caption(i)
        rows.append(row)
    # Not a mesh: a failed row in the middle of shard 3, never an item.
    rows.insert(13, {"id": "broken", "uri": "BROKEN", "license": "cc0", "year": "1999"})
    return rows


def make_job(tmp):
    """Converts the job in `tmp/job` (resolution 32, four items a shard) and returns it."""
    broken = tmp / "broken.obj"
    broken.write_text("not a mesh\n")
    manifest = tmp / "m.jsonl"
    lines = []
    for row in manifest_rows():
        row = dict(row, uri=str(broken)) if row["uri"] == "BROKEN" else row
        lines.append(json.dumps(row) + "\n")
    manifest.write_text("".join(lines))
    job = tmp / "job"
    run("init", job, "--manifest", manifest, "--resolution", 32, "--shard-size", 4)
    run("run", job, "--workers", 2)
    return job


def triangles(name):
    """Triangles of an example mesh, counted from its file: an OBJ's faces as fans (n - 2
    each), a binary STL's header count; the three boxes have 6 sides of 2 triangles."""
    path = ROOT / "examples" / name
    if name.endswith(".obj"):
        return sum(len(line.split()) - 3 for line in path.read_text().splitlines()
                   if line.startswith("f "))
    if name.endswith(".stl"):
        return struct.unpack("<I", path.read_bytes()[80:84])[0]
    return 6 * 2
