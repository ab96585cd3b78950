"""Remote sources end to end (issue 30, part 1), against servers on loopback: an HTTP server
with injected faults and moto's S3 server. A job whose manifest mixes local paths, HTTP URLs
and s3:// keys converts to the same rows as the same job on local copies; every fault is a
`fetch` failure of its own item with a message naming the URL, and `retry --class fetch`
after the fault cleared finishes the job; `manifest build s3://...` lists a prefix."""

import csv
import hashlib
import json
import shutil

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from remote_servers import FaultyServer, MotoS3, clean_env
from sparc3d_cli import ROOT, frozen_records, run

EXAMPLES = ROOT / "examples"
GLTF_DATA = ROOT / "sparcubes" / "tests" / "data"
# Short limits so that a stalled server fails an item in seconds, not minutes.
FAST = {
    "SPARC3D_FETCH_READ_TIMEOUT": "1",
    "SPARC3D_FETCH_CONNECT_TIMEOUT": "2",
    "SPARC3D_FETCH_RETRIES": "2",
}


@pytest.fixture(scope="module")
def s3():
    server = MotoS3()
    yield server
    server.close()


@pytest.fixture()
def web(tmp_path):
    root = tmp_path / "web"
    root.mkdir()
    server = FaultyServer(root)
    yield server, root
    server.close()


def write_manifest(path, rows, columns=("uri",)):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(columns)
        for r in rows:
            w.writerow(r if isinstance(r, (list, tuple)) else [r])
    return path


def job_rows(job):
    """Every row of a job's shards as a table in item order, without the columns that say
    where the source was (`uri`) or how long it took (`time_*`, `attempts`)."""
    files = sorted((job / "shards").glob("part-*.parquet"))
    table = pa.concat_tables([pq.read_table(f) for f in files])
    table = table.sort_by("item_index")
    keep = [c for c in table.column_names
            if c != "uri" and not c.startswith("time_") and c != "attempts"]
    return table.select(keep)


def sha256(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def status(job, env):
    return json.loads(run("status", job, "--json", env=env).stdout)


def test_a_job_over_http_s3_and_local_files_converts_as_its_local_copies(tmp_path, web, s3):
    server, root = web
    local = tmp_path / "local"
    local.mkdir()
    names = ["cube.off", "sphere.obj", "box_textured.glb", "wuson.stl",
             "Mesh_PrimitiveMode_04.gltf", "Mesh_PrimitiveMode_05.gltf"]
    for n in names:
        src = EXAMPLES / n if (EXAMPLES / n).exists() else GLTF_DATA / n
        shutil.copy(src, local / n)
    for n in ["Mesh_PrimitiveMode_04.bin", "Mesh_PrimitiveMode_05.bin"]:
        shutil.copy(GLTF_DATA / n, local / n)
    # Over HTTP: an OFF and a glTF whose buffer is a separate file beside it.
    (root / "m").mkdir()
    for n in ["cube.off", "Mesh_PrimitiveMode_04.gltf", "Mesh_PrimitiveMode_04.bin"]:
        shutil.copy(local / n, root / "m" / n)
    # In the bucket: an OBJ, a GLB and a second glTF with its buffer under the same prefix.
    for n in ["sphere.obj", "box_textured.glb", "Mesh_PrimitiveMode_05.gltf",
              "Mesh_PrimitiveMode_05.bin"]:
        s3.put("meshes", "set/" + n, (local / n).read_bytes())
    remote = [
        server.url + "/m/cube.off",
        "s3://meshes/set/sphere.obj",
        "s3://meshes/set/box_textured.glb",
        str(local / "wuson.stl"),
        server.url + "/m/Mesh_PrimitiveMode_04.gltf",
        "s3://meshes/set/Mesh_PrimitiveMode_05.gltf",
    ]
    env = clean_env({**s3.env, **FAST})
    jobs = {}
    for name, uris in [("remote", remote), ("local", [str(local / n) for n in names])]:
        # No id or sha256 column: init identifies every row by its bytes' sha256, fetching
        # the remote ones.
        m = write_manifest(tmp_path / (name + ".csv"), [[u, "cc-by"] for u in uris],
                           ("uri", "license"))
        job = tmp_path / ("job_" + name)
        run("init", job, "--manifest", m, "--resolution", 32, "--shard-size", 4, env=env)
        run("run", job, "--workers", 2, env=env)
        assert status(job, env)["ok"] == len(names), run("failures", job, env=env).stdout
        jobs[name] = job

    frozen = frozen_records(jobs["remote"])
    assert [f["uri"] for f in frozen] == remote
    assert [f["id"] for f in frozen] == [sha256(local / n) for n in names]
    # A local glTF's id also covers the buffer files beside it (`<sha256>-<16 hex>`); a remote
    # one keeps its sha256, its siblings being fetched when converted, not when listed.
    local_ids = [f["id"] for f in frozen_records(jobs["local"])]
    for n, i in zip(names, local_ids):
        named = n.endswith(".gltf")
        assert i.startswith(sha256(local / n) + "-") if named else i == sha256(local / n), n
    a, b = job_rows(jobs["remote"]), job_rows(jobs["local"])
    assert a.column_names == b.column_names
    a, b = a.drop_columns(["id"]), b.drop_columns(["id"])
    assert a.equals(b), "the remote job's rows differ from its local copies'"
    # The glTF buffers were fetched from beside their glTF files.
    assert server.hits.get("/m/Mesh_PrimitiveMode_04.bin", 0) >= 1

    # `eval` reads each item's source again (as `validate` and the report's pictures do,
    # through the same loader): a remote one is fetched, glTF buffers beside it, and measures
    # as its local copy does.
    def measured(job):
        out = json.loads(run("eval", job, "--sample", len(names), "--json", env=env).stdout)
        assert out["errors"] == 0, out
        return {i["id"]: i["report"] for i in out["items"]}
    hits = server.hits.get("/m/Mesh_PrimitiveMode_04.bin", 0)
    remote_ids = [f["id"] for f in frozen]
    remote_reports, local_reports = measured(jobs["remote"]), measured(jobs["local"])
    assert [remote_reports[i] for i in remote_ids] == [local_reports[i] for i in local_ids]
    assert server.hits.get("/m/Mesh_PrimitiveMode_04.bin", 0) > hits


def test_faults_are_fetch_failures_of_their_items_and_retry_finishes(tmp_path, web, s3):
    server, root = web
    names = ["cube.off", "sphere.obj", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
    for n in names:
        shutil.copy(EXAMPLES / n, root / n)
    s3.put("faults", "later/sphere.obj", (EXAMPLES / "sphere.obj").read_bytes())
    shutil.copy(EXAMPLES / "cube.off", root / "moved.off")
    server.faults.update({
        "/cube.off": ("status", 503, None),           # a 503 storm: every retry fails
        "/sphere.obj": ("truncate",),                 # half the announced body
        "/cube_binary.ply": ("slow", 4),              # past the 1 s read time-out
        "/wuson.stl": ("body", b"solid x\nendsolid x\n"),  # other bytes than the sha256
        "/box_textured.glb": ("status", 503, 2),      # two 503s, then served: retried
        "/old.off": ("redirect", "/moved.off"),       # a redirect is followed
    })
    rows = [
        [server.url + "/cube.off", sha256(EXAMPLES / "cube.off")],
        [server.url + "/sphere.obj", sha256(EXAMPLES / "sphere.obj")],
        [server.url + "/cube_binary.ply", sha256(EXAMPLES / "cube_binary.ply")],
        [server.url + "/wuson.stl", sha256(EXAMPLES / "wuson.stl")],
        [server.url + "/box_textured.glb", sha256(EXAMPLES / "box_textured.glb")],
        [server.url + "/old.off", sha256(EXAMPLES / "cube.off")],
        ["s3://faults/now/sphere.obj", sha256(EXAMPLES / "sphere.obj")],
        [server.url + "/gone.obj", sha256(EXAMPLES / "sphere.obj")],
    ]
    # Two rows with the cube's bytes need ids of their own.
    rows = [[str(i)] + r for i, r in enumerate(rows)]
    m = write_manifest(tmp_path / "m.csv", rows, ("id", "uri", "sha256"))
    env = clean_env({**s3.env, **FAST})
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 32, "--shard-size", 4, env=env)
    r = run("run", job, "--workers", 2, env=env, check=False)
    assert r.returncode == 0, r.stderr  # some items converted: the job is done
    st = status(job, env)
    assert st["ok"] == 2, st  # the retried 503s and the redirect
    lines = run("failures", job, env=env).stdout.splitlines()
    failed = {l.split("\t")[1]: l for l in lines if l.strip()}
    assert sorted(failed) == ["0", "1", "2", "3", "6", "7"], lines
    for line in failed.values():
        assert line.split("\t")[0] == "fetch", line
    assert "503" in failed["0"], failed["0"]
    assert "broke off" in failed["1"] or "truncated" in failed["1"], failed["1"]
    assert "timed out" in failed["2"] or "timeout" in failed["2"].lower(), failed["2"]
    assert "sha256" in failed["3"], failed["3"]
    assert "not found" in failed["6"] and "s3://faults/now/sphere.obj" in failed["6"], failed["6"]
    assert "not found" in failed["7"] and "/gone.obj" in failed["7"], failed["7"]
    assert "testing" not in "\n".join(lines)  # no credential in any message
    assert server.hits["/box_textured.glb"] == 3

    # The faults clear: the server answers, the objects appear; only the fetch failures
    # are converted again, and the job finishes.
    server.faults.clear()
    shutil.copy(EXAMPLES / "sphere.obj", root / "gone.obj")
    s3.put("faults", "now/sphere.obj", (EXAMPLES / "sphere.obj").read_bytes())
    run("retry", job, "--class", "fetch", env=env)
    run("run", job, "--workers", 2, env=env)
    st = status(job, env)
    assert st["ok"] == len(rows), run("failures", job, env=env).stdout


def test_unknown_schemes_and_credentials_in_urls_are_refused_at_init(tmp_path):
    m = write_manifest(tmp_path / "m.csv", [
        str(EXAMPLES / "cube.off"), "ftp://host/a.obj", "https://user:hunter2@host/b.obj"])
    r = run("init", tmp_path / "job", "--manifest", m, check=False)
    assert r.returncode != 0
    assert "row 2: uri: ftp://host/a.obj: unknown scheme `ftp://`" in r.stderr, r.stderr
    assert "row 3" in r.stderr and "credentials inside the URL" in r.stderr, r.stderr
    assert "hunter2" not in r.stderr
    assert not (tmp_path / "job" / "job.json").exists()


def test_missing_credentials_fail_the_item_naming_it(tmp_path, s3):
    s3.put("private", "a/cube.off", (EXAMPLES / "cube.off").read_bytes())
    m = write_manifest(tmp_path / "m.csv", [["x", "s3://private/a/cube.off"]], ("id", "uri"))
    # No key, no profile, and an instance metadata service that refuses connections.
    env = clean_env({"AWS_ENDPOINT_URL": s3.endpoint, "AWS_REGION": "us-east-1",
                     "AWS_METADATA_ENDPOINT": "http://127.0.0.1:9",
                     "AWS_SHARED_CREDENTIALS_FILE": str(tmp_path / "none"), **FAST})
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 32, env=env)
    run("run", job, env=env, check=False)
    lines = [l for l in run("failures", job, env=env).stdout.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("fetch\tx\t"), lines
    assert "s3://private/a/cube.off" in lines[0] and "credentials" in lines[0], lines[0]


def test_manifest_build_lists_a_bucket_prefix(tmp_path, s3):
    names = ["cube.off", "sphere.obj", "box_textured.glb"]
    for n in names:
        s3.put("listing", "meshes/" + n, (EXAMPLES / n).read_bytes())
    s3.put("listing", "meshes/copy/cube.off", (EXAMPLES / "cube.off").read_bytes())
    s3.put("listing", "meshes/README.txt", b"not a mesh")
    s3.put("listing", "other/wuson.stl", (EXAMPLES / "wuson.stl").read_bytes())
    env = clean_env({**s3.env, **FAST})

    out = tmp_path / "m.csv"
    r = run("manifest", "build", "s3://listing/meshes/", "-o", out, env=env)
    assert "1 identical duplicates" in r.stderr, r.stderr
    got = list(csv.DictReader(open(out)))
    assert [g["uri"] for g in got] == [
        "s3://listing/meshes/box_textured.glb", "s3://listing/meshes/copy/cube.off",
        "s3://listing/meshes/sphere.obj"]
    assert [g["id"] for g in got] == [
        sha256(EXAMPLES / n) for n in ["box_textured.glb", "cube.off", "sphere.obj"]]

    keys = tmp_path / "keys.csv"
    run("manifest", "build", "s3://listing/meshes/", "-o", keys, "--id-from", "key", env=env)
    got = list(csv.DictReader(open(keys)))
    assert [g["id"] for g in got] == [
        "meshes/box_textured.glb", "meshes/copy/cube.off", "meshes/cube.off",
        "meshes/sphere.obj"]
    assert all(g["sha256"] == "" for g in got)
    etags = tmp_path / "etags.csv"
    run("manifest", "build", "s3://listing/meshes/", "-o", etags, "--id-from", "etag", env=env)
    got = list(csv.DictReader(open(etags)))
    md5 = hashlib.md5((EXAMPLES / "cube.off").read_bytes()).hexdigest()
    assert md5 in [g["id"] for g in got]

    # A job made from the listing converts the objects.
    job = tmp_path / "job"
    run("init", job, "--manifest", out, "--resolution", 32, env=env)
    run("run", job, env=env)
    assert status(job, env)["ok"] == 3

    # A listing that fails is a named error, and the output is not written.
    out.write_text("kept\n")
    r = run("manifest", "build", "s3://no-such-bucket/meshes/", "-o", out, env=env, check=False)
    assert r.returncode != 0
    assert "listing s3://no-such-bucket/meshes/" in r.stderr, r.stderr
    assert out.read_text() == "kept\n"


def test_a_listing_that_fails_halfway_is_named_and_writes_nothing(tmp_path, web):
    # The HTTP server plays an S3 endpoint whose listing's second page always fails.
    server, _ = web
    server.faults["/halfway"] = ("s3list",)
    env = clean_env({"AWS_ENDPOINT_URL": server.url, "AWS_ACCESS_KEY_ID": "k",
                     "AWS_SECRET_ACCESS_KEY": "s", "AWS_REGION": "us-east-1", **FAST})
    (tmp_path / "out").mkdir()
    out = tmp_path / "out" / "m.csv"
    r = run("manifest", "build", "s3://halfway/meshes/", "-o", out, env=env, check=False)
    assert r.returncode != 0
    assert "listing s3://halfway/meshes/; nothing was written" in r.stderr, r.stderr
    assert "the listing failed after 1 objects" in r.stderr, r.stderr
    assert not list((tmp_path / "out").iterdir())  # no manifest, no temporary file
    assert server.hits["/halfway"] >= 2


def test_an_object_over_the_byte_cap_is_too_large(tmp_path, web):
    server, root = web
    shutil.copy(EXAMPLES / "wuson.stl", root / "big.stl")
    shutil.copy(EXAMPLES / "cube.off", root / "small.off")
    size = (EXAMPLES / "wuson.stl").stat().st_size
    m = write_manifest(tmp_path / "m.csv", [["big", server.url + "/big.stl"],
                                            ["small", server.url + "/small.off"]], ("id", "uri"))
    env = clean_env({**FAST, "SPARC3D_FETCH_MAX_BYTES": str(size - 1)})
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 32, env=env)
    run("run", job, env=env)
    lines = [l for l in run("failures", job, env=env).stdout.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("too_large\tbig\t"), lines
    assert "the object is %d bytes, over the cap of %d" % (size, size - 1) in lines[0], lines[0]


def test_bodies_without_a_length_gzip_and_an_unasked_part(tmp_path, web):
    """Issue 41, defect 6: a body without Content-Length (chunked, or ended by the connection's
    close) failed every time; a gzip-encoded one was taken as the object (a sha256 mismatch,
    or without a sha256 a file that does not parse); a 206 to a plain GET was taken for the
    whole object. Bodies of no length and gzip convert as the files; the 206 and a coding
    sparc3d does not decode are `fetch` failures that say so."""
    server, root = web
    faults = {
        "sphere.obj": ("chunked",),
        "cube.off": ("close",),
        "wuson.stl": ("encoded", "gzip"),
        "box_textured.glb": ("encoded", "gzip"),
        "cube_binary.ply": ("partial",),
        "brotli.off": ("encoded", "br"),
    }
    for n, fault in faults.items():
        shutil.copy(EXAMPLES / n.replace("brotli.off", "cube.off"), root / n)
        server.faults["/" + n] = fault
    # The gzip-encoded glTF without a sha256: its id is the decoded file's.
    rows = [[n, server.url + "/" + n, "" if n == "box_textured.glb" else sha256(root / n)]
            for n in faults]
    m = write_manifest(tmp_path / "m.csv", rows, ("id", "uri", "sha256"))
    env = clean_env(FAST)
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 32, "--shard-size", 3, env=env)
    run("run", job, "--workers", 2, env=env, check=False)
    lines = run("failures", job, env=env).stdout.splitlines()
    failed = {l.split("\t")[1]: l for l in lines if l.strip()}
    assert sorted(failed) == ["brotli.off", "cube_binary.ply"], lines
    assert failed["cube_binary.ply"].startswith("fetch\t"), failed
    assert "206" in failed["cube_binary.ply"], failed["cube_binary.ply"]
    assert "Content-Encoding" in failed["brotli.off"] and '"br"' in failed["brotli.off"], failed
    table = job_rows(job).to_pylist()
    ok = {r["id"]: r for r in table if r["status"] == "ok"}
    assert sorted(ok) == ["box_textured.glb", "cube.off", "sphere.obj", "wuson.stl"], table
    for n, r in ok.items():
        assert r["source_sha256"] == sha256(root / n), n
    assert server.hits["/cube_binary.ply"] == 1  # a 206 is refused, not retried


def png_bytes(rgba, size=4):
    """A `size` × `size` PNG of one colour."""
    import struct
    import zlib

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    rows = b"".join(b"\0" + bytes(rgba) * size for _ in range(size))
    header = struct.pack(">IIBBBBB", size, size, 8, 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def test_a_texture_or_material_library_that_fails_to_download_is_a_fetch_row(tmp_path, web):
    """Issue 64 item 2: a file beside a remote mesh that its appearance reads and that cannot
    be downloaded fails the item as `fetch` (before: an `ok` row without that appearance, and
    nothing for `retry --class fetch`); once it can be fetched, retry converts it with it."""
    server, root = web
    sphere = (EXAMPLES / "sphere.obj").read_text()
    for name in ["a", "b"]:
        text = sphere.replace("mtllib textured_sphere_smooth.mtl", "mtllib %s.mtl" % name)
        (root / ("%s.obj" % name)).write_text(text.replace("usemtl None", "usemtl red"))
        (root / ("%s.mtl" % name)).write_text("newmtl red\nKd 1 1 1\nmap_Kd %s.png\n" % name)
        (root / ("%s.png" % name)).write_bytes(png_bytes([255, 0, 0, 255]))
    server.faults.update({
        "/a.mtl": ("status", 503, None),  # the material library: a 503 storm
        "/b.png": ("status", 503, None),  # the texture its library names: a 503 storm
    })
    rows = [[server.url + "/a.obj"], [server.url + "/b.obj"]]
    m = write_manifest(tmp_path / "m.csv", rows)
    config = tmp_path / "attributes.toml"
    config.write_text("[attributes]\nenabled = true\n")
    env = clean_env(FAST)
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 32, "--config", config, env=env)
    r = run("run", job, "--workers", 1, env=env, check=False)
    assert status(job, env)["ok"] == 0, r.stderr
    lines = [l for l in run("failures", job, env=env).stdout.splitlines() if l.strip()]
    assert len(lines) == 2, lines
    for line, file in zip(sorted(lines, key=lambda l: "/b.obj" in l), ["/a.mtl", "/b.png"]):
        assert line.split("\t")[0] == "fetch", line
        assert server.url + file in line and "503" in line, line

    server.faults.clear()
    run("retry", job, "--class", "fetch", env=env)
    run("run", job, "--workers", 1, env=env)
    assert status(job, env)["ok"] == 2, run("failures", job, env=env).stdout
    table = job_rows(job)
    assert table.column("textures").to_pylist() == [1, 1]
    assert table.column("appearance_not_read").to_pylist() == ["", ""]


def test_a_texture_over_the_byte_cap_is_named_in_an_ok_row(tmp_path, web):
    """A texture beside a remote mesh that is over the byte cap is not retried: the item is
    `ok`, the texture named in `appearance_not_read` with the cap."""
    server, root = web
    sphere = (EXAMPLES / "sphere.obj").read_text()
    (root / "c.obj").write_text(sphere.replace(
        "mtllib textured_sphere_smooth.mtl", "mtllib c.mtl").replace("usemtl None", "usemtl red"))
    (root / "c.mtl").write_text("newmtl red\nKd 1 1 1\nmap_Kd c.png\n")
    # Incompressible pixels: the PNG is larger than the cap, the mesh is not.
    (root / "c.png").write_bytes(big_png(300))
    assert (root / "c.png").stat().st_size > 200_000 > (root / "c.obj").stat().st_size
    m = write_manifest(tmp_path / "m.csv", [[server.url + "/c.obj"]])
    config = tmp_path / "attributes.toml"
    config.write_text("[attributes]\nenabled = true\n")
    env = clean_env({**FAST, "SPARC3D_FETCH_MAX_BYTES": "200000"})
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 32, "--config", config, env=env)
    run("run", job, "--workers", 1, env=env)
    assert status(job, env)["ok"] == 1, run("failures", job, env=env).stdout
    not_read = job_rows(job).column("appearance_not_read").to_pylist()[0]
    assert "c.png" in not_read and "200000" in not_read, not_read


def big_png(size):
    """A `size` × `size` PNG of random pixels (it does not compress)."""
    import os
    import struct
    import zlib

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    rows = b"".join(b"\0" + os.urandom(4 * size) for _ in range(size))
    header = struct.pack(">IIBBBBB", size, size, 8, 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def test_an_endless_body_without_a_length_is_too_large_at_the_cap(tmp_path, web):
    """Issue 64 item 8: a body with no Content-Length that never ends stops at the byte cap
    as `too_large`, within the item's memory (here a cap of 1 GiB under 1.5 GiB of item
    memory; before, the growing buffer passed the memory limit and the item crashed)."""
    server, root = web
    server.faults["/endless.obj"] = ("endless",)
    m = write_manifest(tmp_path / "m.csv", [["a", server.url + "/endless.obj"]], ("id", "uri"))
    env = clean_env({**FAST, "SPARC3D_FETCH_MAX_BYTES": str(1 << 30)})
    job = tmp_path / "job"
    run("init", job, "--manifest", m, "--resolution", 16, env=env)
    run("run", job, "--workers", 1, "--item-memory", "1536M", env=env, check=False)
    lines = [l for l in run("failures", job, env=env).stdout.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("too_large\t"), lines
    assert "1073741824" in lines[0], lines
