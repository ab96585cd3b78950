"""Jobs in a bucket under faults of issue 41 ("Reliability, round four"), against moto's S3
server on loopback: two `init`s at once on one URL never leave a job of one's `job.json` and
the other's manifest, and a job so mixed by an older sparc3d is said to be damaged with what
to do; a store down for some seconds (shorter than a lease) fails no item and no upload; a
bucket deleted under a running worker is said to be gone, not taken over."""

import hashlib
import json
import os
import signal
import subprocess
import time

import pytest

from remote_servers import MotoS3, clean_env
from s3_proxy import S3Proxy
from sparc3d_cli import ROOT, run, sparc3d_bin

EXAMPLES = ROOT / "examples"
BUCKET = "reliable-bkt"


@pytest.fixture(scope="module")
def s3():
    server = MotoS3()
    server.client.create_bucket(Bucket=BUCKET)
    yield server
    server.close()


def env_for(s3, scratch, endpoint=None):
    extra = {"SPARC3D_SCRATCH": str(scratch)}
    if endpoint:
        extra["AWS_ENDPOINT_URL"] = endpoint
    return clean_env({**s3.env, **extra})


def manifest(tmp_path, name, files):
    path = tmp_path / name
    path.write_text("uri\n" + "".join(f"{EXAMPLES / f}\n" for f in files))
    return path


def get(s3, bucket, key):
    return s3.client.get_object(Bucket=bucket, Key=key)["Body"].read()


def wait_for(predicate, seconds, what):
    deadline = time.time() + seconds
    while not predicate():
        assert time.time() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def test_two_inits_at_once_with_different_manifests_never_mix_their_files(tmp_path, s3):
    """Defect 3: both uploaded their manifest, then created job.json if absent; the winner of
    job.json could get the loser's manifest. job.json's uploads are held back 1 s here, so that
    both manifests are up before either job.json (the race the fault probe hit in 3 of 4
    trials)."""
    small = manifest(tmp_path, "small.csv", ["cube.off"])
    large = manifest(tmp_path, "large.csv", ["cube.off", "sphere.obj", "wuson.stl"])
    proxy = S3Proxy(s3.port)
    try:
        for trial in range(3):
            url = f"s3://{BUCKET}/race-{trial}"
            proxy.add_fault("PUT", f"race-{trial}/job.json", ("delay", 1.0), 2)
            inits = [subprocess.Popen(
                [sparc3d_bin(), "init", url, "--manifest", str(m), "--resolution", "32"],
                env=env_for(s3, tmp_path / f"scratch-{trial}-{i}", proxy.endpoint),
                stderr=subprocess.PIPE, text=True) for i, m in enumerate([small, large])]
            errs = [p.communicate(timeout=120)[1] for p in inits]
            codes = [p.returncode for p in inits]
            assert sorted(codes) == [0, 1], (codes, errs)
            job = json.loads(get(s3, BUCKET, f"race-{trial}/job.json"))
            pages = job["manifest_pages"]
            root = hashlib.sha256("".join(p["sha256"] + "\n" for p in pages).encode())
            assert job["manifest_sha256"] == root.hexdigest(), (trial, errs)
            lines = []
            for p, pin in enumerate(pages):
                page = get(s3, BUCKET, f"race-{trial}/manifest/index-{p:05d}.{pin['sha256'][:16]}.tsv")
                assert hashlib.sha256(page).hexdigest() == pin["sha256"], (trial, errs)
                for line in page.decode().splitlines():
                    shard, _, _, sha = line.split("\t")
                    part = get(s3, BUCKET, f"race-{trial}/manifest/part-{int(shard):05d}.{sha[:16]}.jsonl")
                    assert hashlib.sha256(part).hexdigest() == sha, (trial, errs)
                    lines += part.splitlines()
            assert job["items"] == len(lines) == [1, 3][codes.index(0)]
            loser = errs[codes.index(1)]
            assert url in loser and "another" in loser and "use another prefix" in loser, loser
            st = run("status", url, "--json", env=env_for(s3, tmp_path / "scratch-st"))
            assert json.loads(st.stdout)["pending"] == job["items"]
    finally:
        proxy.close()


def test_a_replaced_slice_is_said_damaged_with_what_to_do(tmp_path, s3):
    """Defect 7 of an earlier round (a job mixed by two `init`s failed every command naming a
    temporary copy), as slices have it: a slice object replaced after `init` (here by another
    job's slice of the same shard) is said of the bucket's object, with what to do."""
    url = f"s3://{BUCKET}/mixed"
    env = env_for(s3, tmp_path / "scratch")
    run("init", url, "--manifest", manifest(tmp_path, "one.csv", ["cube.off"]), env=env)
    other = tmp_path / "other"
    run("init", other, "--manifest",
        manifest(tmp_path, "three.csv", ["cube.off", "sphere.obj", "wuson.stl"]))
    listed = s3.client.list_objects_v2(Bucket=BUCKET, Prefix="mixed/manifest/part-00000.")
    key = listed["Contents"][0]["Key"]
    theirs = next((other / "manifest").glob("part-00000.*.jsonl"))
    s3.client.put_object(Bucket=BUCKET, Key=key, Body=theirs.read_bytes())
    for command in (["run", url], ["ls", url]):
        r = run(*command, env=env_for(s3, tmp_path / "scratch-2"), check=False)
        assert r.returncode != 0, command
        said = r.stderr
        assert f"the job at {url} is damaged" in said, said
        assert f"{url}/{key[len('mixed/'):]}" in said and "replaced after `init`" in said, said
        assert "make the job again under another prefix" in said, said


@pytest.mark.parametrize("fault", ["fetch", "lease"])
def test_a_store_down_for_seconds_fails_no_item_and_no_upload(tmp_path, s3, fault):
    """Defect 5: the store client's retries ended 1.5-3.5 s after the first attempt, and the
    lease's renewal before the upload gave up at its first failed write, though the lease had
    a minute left. The store goes down for 5 s (every connection closed unanswered) at the
    item's fetch, or at that renewal: the item converts and the shard is committed."""
    names = ["cube.off", "sphere.obj"]
    for n in names:
        s3.put("outage-src", n, (EXAMPLES / n).read_bytes())
    m = tmp_path / "m.csv"
    m.write_text("uri\n" + "".join(f"s3://outage-src/{n}\n" for n in names))
    url = f"s3://{BUCKET}/outage-{fault}"
    run("init", url, "--manifest", m, "--resolution", 32, "--shard-size", 2,
        env=env_for(s3, tmp_path / "scratch-init"))
    proxy = S3Proxy(s3.port)
    try:
        if fault == "fetch":
            proxy.add_fault("GET", "/outage-src/", ("down", 5.0), 1)
        else:  # the first PUT of the lease takes it; the second renews it before the upload
            proxy.add_fault("PUT", ".lease", ("down", 5.0), 1, skip=1)
        r = run("work", url, "--all", env=env_for(s3, tmp_path / "scratch", proxy.endpoint),
                check=False)
        assert r.returncode == 0, r.stderr
        assert not [f for f in proxy.faults if f[3] > 0], f"fault not met: {proxy.faults}"
        assert proxy.refused >= 2, "the outage was met by retries"
    finally:
        proxy.close()
    st = json.loads(run("status", url, "--json", env=env_for(s3, tmp_path / "read")).stdout)
    assert (st["shards_done"], st["ok"], st["failed"]) == (1, 2, 0), st


def test_a_bucket_deleted_under_a_worker_is_said_gone(tmp_path, s3):
    """Defect 7: a worker whose bucket was deleted mid-run said its lease was "taken over by
    another worker"."""
    s3.client.create_bucket(Bucket="doomed")
    url = "s3://doomed/job"
    env = env_for(s3, tmp_path / "scratch")
    run("init", url, "--manifest", manifest(tmp_path, "m.csv", ["wuson.stl", "sphere.obj"]),
        "--resolution", 256, "--shard-size", 2, env=env)
    worker = subprocess.Popen(
        [sparc3d_bin(), "work", url, "--shard-index", "0", "--lease-ttl", "3"],
        env=env, stderr=subprocess.PIPE, text=True)
    try:
        listed = lambda: s3.client.list_objects_v2(Bucket="doomed").get("Contents", [])
        wait_for(lambda: any(o["Key"].endswith(".lease") for o in listed())
                 or worker.poll() is not None, 60, "the lease")
        assert worker.poll() is None, "the worker finished before the bucket was deleted"
        for o in listed():
            s3.client.delete_object(Bucket="doomed", Key=o["Key"])
        s3.client.delete_bucket(Bucket="doomed")
        err = worker.communicate(timeout=120)[1]
    finally:
        if worker.poll() is None:
            os.kill(worker.pid, signal.SIGKILL)
    assert "is gone" in err and "deleted" in err, err
    assert "taken over" not in err, err
