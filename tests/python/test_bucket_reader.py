"""The Python reader takes a job URL (docs/RELIABILITY.md, "The Python reader"): a job whose
home is a bucket, laid out as the bucket's writers leave it (each shard's data under a name of
its writer's, `part-NNNNN.<token>.parquet`, named by the record's `object`; records without a
stamp; uploads no record names; `state/`), reads the same items as its local folder, through
moto's S3 server on loopback. A rewritten object is left out and named, a URL without a job is
a clear error, and a dataset pickled into another process (a DataLoader worker) reads there.
A local record may name its data file too."""

import json
import os
import pickle
import re
import shutil
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest
import torch.utils.data

from remote_servers import s3_environment
from sparc3d_cli import ROOT, run

try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    if os.environ.get("SPARC3D_CI") == "1":
        raise
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

from sparc3d_reader import location

MESHES = ["sphere.obj", "cube.off", "cube_binary.ply", "wuson.stl", "box_textured.glb"]
IDS = ["item%d" % i for i in range(5)]  # shard size 2: shards of items 0-1, 2-3 and 4
BUCKET = "jobs"


@pytest.fixture(scope="module")
def local_job(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bucket-reader")
    manifest = tmp / "m.jsonl"
    manifest.write_text("".join(
        json.dumps({"id": IDS[i], "uri": str(ROOT / "examples" / MESHES[i])}) + "\n"
        for i in range(len(IDS))))
    job = tmp / "job"
    run("init", job, "--manifest", manifest, "--resolution", 32, "--shard-size", 2)
    run("run", job)
    return job


@pytest.fixture(scope="module")
def s3():
    """moto's S3 server, with this process's environment set to reach it (the reader reads
    AWS_ENDPOINT_URL and the credentials from the environment)."""
    with s3_environment() as server:
        yield server


def token(shard):
    return "host_%d_ab12cd" % shard


def upload(s3, job, prefix):
    """The local job into the bucket as its writers leave it; returns the job URL."""
    s3.put(BUCKET, f"{prefix}/job.json", (job / "job.json").read_bytes())
    for path in sorted((job / "manifest").iterdir()):
        s3.put(BUCKET, f"{prefix}/manifest/{path.name}", path.read_bytes())
    for path in sorted((job / "shards").glob("part-*.complete.json")):
        record = json.loads(path.read_text())
        n = record["shard"]
        name = f"part-{n:05d}.{token(n)}.parquet"
        # The data first, then the record that names it (created only if absent).
        s3.put(BUCKET, f"{prefix}/shards/{name}", (job / "shards" / f"part-{n:05d}.parquet").read_bytes())
        record.pop("stamp")
        record["object"] = name
        s3.put(BUCKET, f"{prefix}/shards/{path.name}", json.dumps(record).encode())
    # The upload of a writer that lost the race for shard 0 (other rows: read, it would show)
    # and a worker's lease.
    s3.put(BUCKET, f"{prefix}/shards/part-00000.deadbeef.parquet",
           (job / "shards" / "part-00001.parquet").read_bytes())
    s3.put(BUCKET, f"{prefix}/state/leases/part-00000.json", b'{"owner": "host_1"}')
    return f"s3://{BUCKET}/{prefix}"


def read_all(job, verify=True):
    """Items of `iter_items` and of `SparseCubesDataset` (they must agree), and the
    ShardWarning messages."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        items = list(reader.iter_items(job, verify=verify))
        ds = reader.SparseCubesDataset(job, verify=verify)
        assert ds.ids == [it["id"] for it in items]
        for i, it in enumerate(items):
            assert_same_item(ds[i], it)
    return items, [str(w.message) for w in caught if issubclass(w.category, reader.ShardWarning)]


def assert_same_item(a, b):
    assert a.keys() == b.keys()
    for k in a:
        if isinstance(a[k], np.ndarray):
            assert a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]), (a["id"], k)
        else:
            assert a[k] == b[k], (a["id"], k)


def assert_same_items(a, b):
    assert [it["id"] for it in a] == [it["id"] for it in b]
    for x, y in zip(a, b):
        assert_same_item(x, y)


def test_a_job_url_reads_the_items_of_its_local_folder(local_job, s3):
    url = upload(s3, local_job, "clean")
    local, msgs = read_all(local_job)
    assert [it["id"] for it in local] == IDS and msgs == []
    for job, verify in [(url, True), (url, "quick"), (url, False), (url + "/", True)]:
        items, msgs = read_all(job, verify)
        assert_same_items(items, local)
        # The lost upload and state/ are not shards and not worth a word.
        assert msgs == []
    paths = reader.shard_paths(url)
    assert [str(p) for p in paths] == [f"{url}/shards/part-{n:05d}.{token(n)}.parquet" for n in range(3)]
    assert reader.read_job_config(url) == reader.read_job_config(local_job)
    assert reader.jobs.open_job(url).fingerprint == reader.jobs.open_job(local_job).fingerprint
    rows = list(reader.iter_tensor_rows(url, ["coords"]))
    assert [r["id"] for r in rows] == IDS
    assert all(np.array_equal(r["coords"].astype(np.int32).reshape(-1, 3), it["coords"])
               for r, it in zip(rows, local))


def test_quick_hashes_only_an_object_rewritten_after_its_record(local_job, s3, monkeypatch):
    url = upload(s3, local_job, "quick")
    hashed = []
    sha256 = location.sha256
    monkeypatch.setattr(location, "sha256", lambda p: hashed.append(str(p)) or sha256(p))
    assert [it["id"] for it in read_all(url, "quick")[0]] == IDS
    assert hashed == []  # every object older than its record: trusted without a download
    # Shard 1's object rewritten, a byte flipped (same size), a second after its record.
    time.sleep(1.1)
    name = f"shards/part-00001.{token(1)}.parquet"
    flip(s3, f"quick/{name}")
    items, msgs = read_all(url, "quick")
    assert [it["id"] for it in items] == IDS[:2] + IDS[4:]
    assert any(f"{url}/{name} has sha256" in m for m in msgs), msgs
    assert f"{url}/{name}" in hashed


def flip(s3, key):
    data = bytearray(s3.client.get_object(Bucket=BUCKET, Key=key)["Body"].read())
    data[len(data) // 2] ^= 0x10
    s3.client.put_object(Bucket=BUCKET, Key=key, Body=bytes(data))


def test_a_rewritten_object_is_left_out_and_named(local_job, s3):
    url = upload(s3, local_job, "altered")
    name = f"shards/part-00001.{token(1)}.parquet"
    flip(s3, f"altered/{name}")
    items, msgs = read_all(url, True)
    assert [it["id"] for it in items] == IDS[:2] + IDS[4:]
    assert any(re.search(re.escape(f"{url}/{name} is not read") + ".* has sha256 .* its completion "
                         "record says", m) for m in msgs), msgs
    # Its record naming an object that is gone: left out too.
    s3.client.delete_object(Bucket=BUCKET, Key=f"altered/{name}")
    items, msgs = read_all(url, False)
    assert [it["id"] for it in items] == IDS[:2] + IDS[4:]
    assert any(f"{url}/{name} is missing" in m for m in msgs), msgs


def test_a_stray_in_a_buckets_shards_is_named_but_not_an_unnamed_upload(local_job, s3):
    url = upload(s3, local_job, "stray")
    s3.put(BUCKET, "stray/shards/notes.parquet", b"x")
    s3.put(BUCKET, "stray/shards/part-00002.older_host.parquet", b"x")
    items, msgs = read_all(url)
    assert [it["id"] for it in items] == IDS
    assert len(msgs) == 2 and all(re.search(r"ignored notes\.parquet in shards/: not one of", m) for m in msgs)


def test_a_url_without_a_job_is_a_clear_error(local_job, s3, tmp_path, monkeypatch):
    upload(s3, local_job, "there")
    entry_points = [reader.iter_items, reader.SparseCubesDataset, reader.shard_paths,
                    reader.read_job_config, reader.jobs.open_job]
    for read in entry_points:
        with pytest.raises(FileNotFoundError, match=re.escape(f"s3://{BUCKET}/nowhere: no job.json there")):
            list(read(f"s3://{BUCKET}/nowhere"))
        with pytest.raises(FileNotFoundError, match="there is no bucket 'nobucket'.*AWS_ENDPOINT_URL"):
            list(read("s3://nobucket/there"))
    with pytest.raises(ValueError, match="ftp://host/job: a job is a local folder or a URL"):
        reader.shard_paths("ftp://host/job")
    # No credentials anywhere (and no metadata service to ask): named, with what to set.
    for k in ("AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY"):
        monkeypatch.delenv(k)
    monkeypatch.setenv("AWS_SHARED_CREDENTIALS_FILE", str(tmp_path / "none"))
    monkeypatch.setenv("AWS_CONFIG_FILE", str(tmp_path / "none"))
    monkeypatch.setenv("AWS_EC2_METADATA_DISABLED", "true")
    with pytest.raises(ValueError, match=rf"s3://{BUCKET}/there: cannot read its job.json .*"
                                         "AWS_ACCESS_KEY_ID and AWS_SECRET_ACCESS_KEY"):
        reader.iter_items(f"s3://{BUCKET}/there").__next__()


def test_a_dataset_of_a_job_url_reads_in_another_process(local_job, s3):
    url = upload(s3, local_job, "pickled")
    ds = reader.SparseCubesDataset(url)
    blob = pickle.dumps(ds)
    assert b"testing" not in blob  # no credentials travel with it
    # A fresh process, as a DataLoader worker started by spawn: it makes its own filesystem.
    code = ("import pickle, sys\n"
            "ds = pickle.load(sys.stdin.buffer)\n"
            "pickle.dump([ds[i] for i in range(len(ds))], sys.stdout.buffer)\n")
    here = os.path.dirname(os.path.dirname(reader.__file__))  # this process's sparc3d_reader
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [here] + [p for p in [os.environ.get("PYTHONPATH")] if p])}
    r = subprocess.run([sys.executable, "-c", code], input=blob, capture_output=True, env=env)
    assert r.returncode == 0, r.stderr.decode()
    assert_same_items(pickle.loads(r.stdout), list(reader.iter_items(local_job)))
    # And in this process, with its filesystems made again.
    location._filesystems.clear()
    again = pickle.loads(blob)
    assert_same_item(again[len(again) - 1], ds[len(ds) - 1])
    # A DataLoader's forked workers, each making its filesystem after the fork.
    loader = torch.utils.data.DataLoader(ds, batch_size=2, num_workers=2, collate_fn=list)
    assert_same_items([it for batch in loader for it in batch], [ds[i] for i in range(len(ds))])


def test_a_local_record_may_name_its_object(local_job, tmp_path):
    job = tmp_path / "job"
    shutil.copytree(local_job, job)
    shards = job / "shards"
    expected = list(reader.iter_items(local_job))
    (shards / "part-00001.parquet").rename(shards / "part-00001.host_9.parquet")
    record = json.loads((shards / "part-00001.complete.json").read_text())
    (shards / "part-00001.complete.json").write_text(json.dumps({**record, "object": "part-00001.host_9.parquet"}))
    for verify in (True, "quick", False):
        items, msgs = read_all(job, verify)
        assert_same_items(items, expected)
        assert msgs == []
    # On disk, a file no record names is a stray, whatever its name; a record naming a file
    # outside its shard's names is damaged.
    shutil.copy(shards / "part-00001.host_9.parquet", shards / "part-00002.other.parquet")
    (shards / "part-00000.complete.json").write_text(json.dumps({**record, "shard": 0, "object": "../job.json"}))
    items, msgs = read_all(job)
    assert [it["id"] for it in items] == IDS[2:]
    assert any("part-00000.parquet: damaged, its completion record names object '../job.json', "
               "not one of shard 0's" in m for m in msgs), msgs
    assert any("ignored part-00002.other.parquet in shards/" in m for m in msgs), msgs
