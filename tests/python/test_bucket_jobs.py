"""Jobs whose home is a bucket (issue 31), against moto's S3 server on loopback: workers that
share nothing but the bucket (each its own scratch folder) give the same content digest as the
same job on disk, leave one upload per shard and no lease or checkpoint behind; a worker
killed with kill -9 mid-shard loses no checkpointed item and every item ends in the shard
exactly once; two workers racing for one shard's lease: one converts it, once; a throttled
bucket (503 SlowDown) and a network cut in the middle of an upload are retried; an upload left
by a worker killed before its record is never read and is cleaned up; `verify` finds a shard
altered in the bucket; a worker SIGSTOPped past its lease and continued after another took
the shard over stops and writes nothing; a bucket without credentials or without the job is a
clear error; `retry` requeues failed items."""

import json
import shutil
import os
import signal
import subprocess
import time

import pytest

from remote_servers import MotoS3, clean_env
from s3_proxy import S3Proxy
from sparc3d_cli import ROOT, run, sparc3d_bin

EXAMPLES = ROOT / "examples"
BUCKET = "jobs-bkt"


@pytest.fixture(scope="module")
def s3():
    server = MotoS3()
    server.client.create_bucket(Bucket=BUCKET)
    yield server
    server.close()


def env_for(s3, scratch):
    return clean_env({**s3.env, "SPARC3D_SCRATCH": str(scratch)})


def keys(s3, prefix):
    out = s3.client.list_objects_v2(Bucket=BUCKET, Prefix=prefix + "/")
    return sorted(o["Key"][len(prefix) + 1:] for o in out.get("Contents", []))


def manifest(tmp_path):
    path = tmp_path / "m.jsonl"
    run("manifest", "build", EXAMPLES, "-o", path)
    return path


def make_jobs(tmp_path, s3, name, resolution, shard_size):
    """The same job twice: in a folder, and at s3://BUCKET/NAME."""
    m = manifest(tmp_path)
    env = env_for(s3, tmp_path / "scratch-init")
    flags = ["--manifest", m, "--resolution", resolution, "--shard-size", shard_size]
    run("init", tmp_path / "local", *flags)
    run("init", f"s3://{BUCKET}/{name}", *flags, env=env)
    return tmp_path / "local", f"s3://{BUCKET}/{name}"


def digest(job, env=None):
    return json.loads(run("inspect", job, "--json", env=env).stdout)["content_digest"]


def test_two_workers_sharing_only_the_bucket_give_the_jobs_digest_on_disk(tmp_path, s3, monkeypatch):
    local, url = make_jobs(tmp_path, s3, "two", 32, 2)
    run("run", local, "--workers", "2")
    # Two array tasks (as a Kubernetes indexed Job runs them), each with its own scratch.
    workers = [subprocess.Popen(
        [sparc3d_bin(), "work", url, "--array", "--shards-per-task", "2"],
        env={**env_for(s3, tmp_path / f"scratch-{w}"), "JOB_COMPLETION_INDEX": str(w)},
        stderr=subprocess.PIPE, text=True) for w in range(2)]
    logs = [w.communicate(timeout=300)[1] for w in workers]
    assert all(w.returncode == 0 for w in workers), logs
    assert [log.count(": written,") for log in logs] == [2, 1], logs
    env = env_for(s3, tmp_path / "scratch-read")
    status = json.loads(run("status", url, "--json", env=env).stdout)
    assert (status["shards_done"], status["ok"], status["pending"]) == (3, 5, 0)
    assert digest(url, env) == digest(local)
    # A read-only command copies the finished shards, within a byte budget.
    small = {**env_for(s3, tmp_path / "scratch-small"), "SPARC3D_VIEW_MAX_BYTES": "1000"}
    refused = run("ls", url, env=small, check=False)
    assert refused.returncode != 0 and "SPARC3D_VIEW_MAX_BYTES" in refused.stderr, refused.stderr
    # A job never changes once made: init again with another config is refused, naming it.
    again = run("init", url, "--manifest", manifest(tmp_path), "--resolution", 64, env=env,
                check=False)
    assert again.returncode != 0 and url in again.stderr, again.stderr
    assert "params.resolution" in again.stderr, again.stderr
    left = keys(s3, "two")
    assert not [k for k in left if k.startswith("state/")], f"leases or checkpoints left: {left}"
    uploads = [k for k in left if k.endswith(".parquet")]
    assert len(uploads) == 3, f"one upload per shard: {uploads}"
    # The Python reader reads the bucket job as the folder.
    import sparc3d_reader as reader
    for k, v in s3.env.items():
        monkeypatch.setenv(k, v)
    from_bucket = [(i["id"], i["coords"].tobytes()) for i in reader.iter_items(url)]
    from_disk = [(i["id"], i["coords"].tobytes()) for i in reader.iter_items(local)]
    assert from_bucket == from_disk


def wait_for(predicate, seconds, what):
    deadline = time.time() + seconds
    while not predicate():
        assert time.time() < deadline, f"timed out waiting for {what}"
        time.sleep(0.05)


def test_status_lists_the_job_once_and_reads_only_what_the_listing_shows(tmp_path, s3):
    """Issue 60: `status` of a bucket job is one listing of its prefix (from `shards/` on, so
    not the frozen manifest's files) and reads of what it shows: each record not read before
    and each lease of an unfinished shard. Before, every shard cost a lease GET and a listing
    of its checkpoints, and every finished one a record GET on every call."""
    rows = tmp_path / "many.jsonl"
    mesh = EXAMPLES / "cube.off"
    rows.write_text("".join(json.dumps({"id": f"cube-{i:03d}", "path": str(mesh)}) + "\n"
                            for i in range(120)))
    url = f"s3://{BUCKET}/scale"
    run("init", url, "--manifest", rows, "--resolution", 32, "--shard-size", 1,
        env=env_for(s3, tmp_path / "scratch-init"))
    proxy = S3Proxy(s3.port)
    env = clean_env({**s3.env, "AWS_ENDPOINT_URL": proxy.endpoint,
                     "SPARC3D_SCRATCH": str(tmp_path / "scratch-status")})

    def status():
        proxy.reset()
        summary = json.loads(run("status", url, "--json", env=env).stdout)
        counts = {f"{m} {k}": n for (m, k), n in proxy.counts.items()}
        return summary, counts

    try:
        summary, counts = status()
        assert (summary["shards"], summary["shards_pending"]) == (120, 120), summary
        assert counts == {"GET job": 1, "GET list": 1}, counts
        for shard in (3, 7):
            run("work", url, "--shard-index", shard, env=env_for(s3, tmp_path / "scratch-w"))
        now = time.time()
        for shard, expires in ((9, now + 600), (11, now - 600)):
            lease = {"owner": f"elsewhere:1:{shard}", "host": "elsewhere", "pid": 1,
                     "heartbeat_at": now - 1, "expires_at": expires, "acquired_at": now - 1}
            s3.client.put_object(Bucket=BUCKET, Key=f"scale/state/part-{shard:05d}.lease",
                                 Body=json.dumps(lease).encode())
        summary, counts = status()
        assert (summary["shards_done"], summary["shards_running"], summary["ok"]) == (2, 1, 2)
        assert counts == {"GET job": 1, "GET list": 1, "GET record": 2, "GET lease": 2}, counts
        # Records are written once: a later status reads only what is new.
        summary, counts = status()
        assert (summary["shards_done"], summary["shards_running"]) == (2, 1), summary
        assert counts == {"GET job": 1, "GET list": 1, "GET lease": 2}, counts
    finally:
        proxy.close()


def test_a_worker_killed_mid_shard_loses_no_checkpointed_item(tmp_path, s3):
    local, url = make_jobs(tmp_path, s3, "kill", 256, 5)
    run("run", local, "--workers", "1")
    first = subprocess.Popen(
        [sparc3d_bin(), "work", url, "--shard-index", "0", "--checkpoint-every", "0.001"],
        env=env_for(s3, tmp_path / "scratch-a"), stderr=subprocess.DEVNULL)
    checkpoints = lambda: [k for k in keys(s3, "kill") if k.endswith(".journal")]
    wait_for(lambda: len(checkpoints()) >= 2 or first.poll() is not None, 120, "checkpoints")
    assert first.poll() is None, "the worker finished before it could be killed"
    first.send_signal(signal.SIGKILL)
    first.wait()
    assert not [k for k in keys(s3, "kill") if k.endswith(".complete.json")]
    second = run("work", url, "--shard-index", "0", "--events",
                 env=env_for(s3, tmp_path / "scratch-b"))
    events = [json.loads(line) for line in second.stdout.splitlines() if line.strip()]
    started = [e for e in events if e.get("event") == "item_started"]
    assert 0 < len(started) <= 5 - 2, f"checkpointed items converted again: {len(started)}"
    env = env_for(s3, tmp_path / "scratch-read")
    rows = run("ls", url, env=env).stdout.splitlines()
    ids = [line.split("\t")[0] for line in rows if line.count("\t") >= 2]
    assert len(ids) == 5 and len(set(ids)) == 5, f"every item exactly once: {rows}"
    assert digest(url, env) == digest(local)


def test_two_workers_racing_for_one_shard_convert_it_once(tmp_path, s3):
    local, url = make_jobs(tmp_path, s3, "race", 64, 5)
    run("run", local, "--workers", "1")
    workers = [subprocess.Popen([sparc3d_bin(), "work", url, "--shard-index", "0"],
                                env=env_for(s3, tmp_path / f"scratch-{w}"),
                                stderr=subprocess.PIPE, text=True) for w in range(2)]
    logs = [w.communicate(timeout=300)[1] for w in workers]
    assert all(w.returncode == 0 for w in workers), logs
    joined = "\n".join(logs)
    assert joined.count(": written,") == 1, joined
    assert "leased by" in joined or "already done" in joined, joined
    uploads = [k for k in keys(s3, "race") if k.endswith(".parquet")]
    assert len(uploads) == 1, uploads
    assert digest(url, env_for(s3, tmp_path / "scratch-read")) == digest(local)


def test_a_throttled_bucket_and_a_cut_upload_are_retried(tmp_path, s3):
    local, url = make_jobs(tmp_path, s3, "faults", 32, 2)
    run("run", local, "--workers", "1")
    proxy = S3Proxy(s3.port)
    try:
        proxy.add_fault("PUT", ".parquet", ("status", 503), 3)
        proxy.add_fault("PUT", ".complete.json", ("status", 503), 2)
        proxy.add_fault("PUT", ".lease", ("status", 503), 2)
        proxy.add_fault("PUT", ".parquet", ("cut",), 1)
        env = clean_env({**s3.env, "AWS_ENDPOINT_URL": proxy.endpoint,
                         "SPARC3D_SCRATCH": str(tmp_path / "scratch")})
        r = run("work", url, "--all", env=env, check=False)
        assert r.returncode == 0, r.stderr
        assert not [f for f in proxy.faults if f[3] > 0], f"faults not met: {proxy.faults}"
    finally:
        proxy.close()
    assert digest(url, env_for(s3, tmp_path / "scratch-read")) == digest(local)


def test_a_leftover_upload_is_never_read_and_an_altered_shard_is_moved_aside_and_redone(tmp_path, s3):
    local, url = make_jobs(tmp_path, s3, "alter", 32, 5)
    run("run", local, "--workers", "1")
    # An upload of a worker killed between its upload and its record.
    s3.client.put_object(Bucket=BUCKET, Key="alter/shards/part-00000.ghost.parquet",
                         Body=b"not a shard")
    env = env_for(s3, tmp_path / "scratch")
    run("run", url, "--workers", "2", env=env)
    assert digest(url, env) == digest(local)
    uploads = [k for k in keys(s3, "alter") if k.endswith(".parquet")]
    assert len(uploads) == 1 and "ghost" not in uploads[0], uploads
    obj = s3.client.get_object(Bucket=BUCKET, Key="alter/" + uploads[0])["Body"].read()
    flipped = obj[:100] + bytes([obj[100] ^ 0xFF]) + obj[101:]
    s3.client.put_object(Bucket=BUCKET, Key="alter/" + uploads[0], Body=flipped)
    r = run("verify", url, env=env_for(s3, tmp_path / "scratch-v"), check=False)
    assert r.returncode == 1, r.stderr
    assert "shard 0: damaged" in r.stdout and f"sparc3d run {url}" in r.stdout, r.stdout
    # Moved aside in the bucket (record, upload and reason kept), then converted again.
    moved = [k for k in keys(s3, "alter") if k.startswith("quarantine/")]
    assert len(moved) == 3 and any(k.endswith("reason.txt") for k in moved), moved
    assert not [k for k in keys(s3, "alter") if k.startswith("shards/")]
    run("run", url, "--workers", "1", env=env)
    assert digest(url, env_for(s3, tmp_path / "scratch-after")) == digest(local)
    assert run("verify", url, env=env_for(s3, tmp_path / "scratch-v2")).returncode == 0


def test_a_missing_job_or_missing_credentials_is_a_clear_error(tmp_path, s3):
    r = run("status", f"s3://{BUCKET}/nothing-here", env=env_for(s3, tmp_path), check=False)
    assert r.returncode != 0
    assert "no job there" in r.stderr, r.stderr
    no_keys = {k: v for k, v in s3.env.items() if not k.startswith("AWS_SECRET")}
    no_keys.pop("AWS_ACCESS_KEY_ID")
    env = clean_env({**no_keys, "SPARC3D_SCRATCH": str(tmp_path),
                     "AWS_EC2_METADATA_DISABLED": "true",
                     "AWS_METADATA_ENDPOINT": "http://127.0.0.1:9"})
    r = run("status", f"s3://{BUCKET}/two", env=env, check=False)
    assert r.returncode != 0
    assert "credentials" in r.stderr.lower(), r.stderr


def test_retry_requeues_failed_items_of_a_bucket_job(tmp_path, s3):
    from remote_servers import FaultyServer
    web = tmp_path / "web"
    web.mkdir()
    shutil.copy(EXAMPLES / "sphere.obj", web / "sphere.obj")
    server = FaultyServer(web)
    try:
        m = tmp_path / "m.csv"
        m.write_text("id,uri\ncube,%s\nsphere,%s/sphere.obj\n" % (EXAMPLES / "cube.off", server.url))
        server.faults["/sphere.obj"] = ("status", 404, None)
        url = f"s3://{BUCKET}/retry"
        env = clean_env({**s3.env, "SPARC3D_SCRATCH": str(tmp_path / "scratch"),
                         "SPARC3D_FETCH_RETRIES": "0"})
        run("init", url, "--manifest", m, "--resolution", 32, "--shard-size", 2, env=env)
        run("run", url, "--workers", "1", env=env)
        before = json.loads(run("status", url, "--json", env=env).stdout)
        assert (before["ok"], before["failed"], before["error_classes"]) == (1, 1, {"fetch": 1})
        server.faults.clear()
        r = run("retry", url, "--class", "fetch", env=env)
        assert "1 failed items in 1 shards queued" in r.stderr, r.stderr
        after_retry = json.loads(run("status", url, "--json", env=env).stdout)
        assert (after_retry["shards_done"], after_retry["ok"]) == (0, 1), after_retry
        run("run", url, "--workers", "1", env=env)
        after = json.loads(run("status", url, "--json", env=env).stdout)
        assert (after["ok"], after["failed"], after["shards_done"]) == (2, 0, 1), after
        assert server.hits["/sphere.obj"] >= 2
    finally:
        server.close()


def test_a_worker_stopped_past_its_lease_leaves_the_shard_to_the_new_holder(tmp_path, s3):
    local, url = make_jobs(tmp_path, s3, "stopped", 256, 5)
    run("run", local, "--workers", "1")
    first = subprocess.Popen(
        [sparc3d_bin(), "work", url, "--shard-index", "0", "--lease-ttl", "2",
         "--checkpoint-every", "0.001"],
        env=env_for(s3, tmp_path / "scratch-a"), stderr=subprocess.PIPE, text=True)
    wait_for(lambda: any(k.endswith(".journal") for k in keys(s3, "stopped"))
             or first.poll() is not None, 120, "a first checkpoint")
    assert first.poll() is None, "the first worker finished before it could be stopped"
    os.kill(first.pid, signal.SIGSTOP)
    try:
        time.sleep(3)  # past its lease: the next worker takes the shard over
        run("work", url, "--shard-index", "0", "--lease-ttl", "2",
            env=env_for(s3, tmp_path / "scratch-b"))
    finally:
        os.kill(first.pid, signal.SIGCONT)
    err = first.communicate(timeout=120)[1]
    # Continued, it finds its lease expired (or, stopped inside its commit, the record there).
    assert "lost its lease" in err or "already done" in err, err
    uploads = [k for k in keys(s3, "stopped") if k.endswith(".parquet")]
    assert len(uploads) == 1, uploads
    assert digest(url, env_for(s3, tmp_path / "scratch-read")) == digest(local)
