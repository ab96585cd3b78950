"""A finished shard changed in the bucket after a read command filled the local copy (issue 41,
defects 1 and 2), against moto's S3 server on loopback: a same-size bit flip, a deleted shard
object, and a shard object replaced by another shard's bytes. `verify` hashes what the bucket
holds (never the local copy), counts a missing object as damaged and goes on; `inspect` and
the other read commands notice that the object is not the one they copied; `status` notices a
replaced object by its ETag; `run` moves a shard whose object is missing, of another size or
replaced aside and converts it again, once. After the documented repair the job's content
digest is the clean one."""

import json

from test_bucket_jobs import BUCKET, digest, env_for, keys, make_jobs, s3  # noqa: F401 (fixture)
from sparc3d_cli import run


def finished_jobs(tmp_path, s3, name):
    """The job on disk and in the bucket, both run; the bucket job read once (so that its
    local copy holds every shard); its clean digest and the environment of its scratch."""
    local, url = make_jobs(tmp_path, s3, name, 32, 2)
    run("run", local, "--workers", "1")
    env = env_for(s3, tmp_path / "scratch")
    run("run", url, "--workers", "1", env=env)
    clean = digest(local)
    assert digest(url, env) == clean
    return url, env, clean


def shard_key(s3, name, shard):
    """The key of the object shard `shard`'s record names."""
    record = s3.client.get_object(
        Bucket=BUCKET, Key=f"{name}/shards/part-{shard:05d}.complete.json")["Body"].read()
    return f"{name}/shards/" + json.loads(record)["object"]


def read_object(s3, key):
    return s3.client.get_object(Bucket=BUCKET, Key=key)["Body"].read()


def status(url, env):
    return json.loads(run("status", url, "--json", env=env).stdout)


def test_a_same_size_bit_flip_after_a_read_is_found_by_verify_and_redone(tmp_path, s3):
    url, env, clean = finished_jobs(tmp_path, s3, "flip")
    key = shard_key(s3, "flip", 1)
    data = read_object(s3, key)
    s3.client.put_object(Bucket=BUCKET, Key=key,
                         Body=data[:200] + bytes([data[200] ^ 0x01]) + data[201:])
    # status notices the replaced object by the ETag its listing shows.
    assert status(url, env)["shards_damaged"] == 1
    # inspect, in the same scratch as the read above, does not trust its local copy.
    r = run("inspect", url, env=env, check=False)
    assert r.returncode != 0 and "shard 1" in r.stderr, r.stderr
    r = run("verify", url, "--dry-run", env=env, check=False)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "shard 1: damaged" in r.stdout and "sha256" in r.stdout, r.stdout
    assert "2 good, 1 damaged" in r.stdout, r.stdout
    assert read_object(s3, key) != data, "--dry-run leaves the shard where it is"
    # The documented repair: verify moves it aside, run converts it again.
    r = run("verify", url, env=env, check=False)
    assert r.returncode == 1 and "moved aside" in r.stdout, r.stdout
    assert [k for k in keys(s3, "flip") if k.endswith("reason.txt")], keys(s3, "flip")
    run("run", url, "--workers", "1", env=env)
    assert digest(url, env) == clean
    assert run("verify", url, env=env).returncode == 0


def test_a_deleted_shard_object_is_counted_damaged_and_converted_again(tmp_path, s3):
    url, env, clean = finished_jobs(tmp_path, s3, "gone")
    s3.client.delete_object(Bucket=BUCKET, Key=shard_key(s3, "gone", 1))
    assert status(url, env)["shards_damaged"] == 1
    r = run("inspect", url, env=env, check=False)
    assert r.returncode != 0 and "shard 1" in r.stderr and "missing" in r.stderr, r.stderr
    r = run("verify", url, "--dry-run", env=env, check=False)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "shard 1: damaged" in r.stdout and "missing" in r.stdout, r.stdout
    assert "3 of 3 shards finished: 2 good, 1 damaged" in r.stdout, r.stdout
    # run alone moves it aside and converts it again (it used to say "already done").
    r = run("run", url, "--workers", "1", env=env)
    assert "moved aside" in r.stderr, r.stderr
    assert digest(url, env) == clean
    # verify then run, as documented.
    s3.client.delete_object(Bucket=BUCKET, Key=shard_key(s3, "gone", 0))
    r = run("verify", url, env=env, check=False)
    assert r.returncode == 1 and "shard 0: damaged" in r.stdout, r.stdout
    assert "2 good, 1 damaged" in r.stdout, r.stdout
    assert "shards/part-00000.complete.json" not in keys(s3, "gone")
    run("run", url, "--workers", "1", env=env)
    assert digest(url, env) == clean
    assert run("verify", url, env=env).returncode == 0


def test_a_shard_replaced_by_another_shards_bytes_is_noticed_and_redone_once(tmp_path, s3):
    url, env, clean = finished_jobs(tmp_path, s3, "swap")
    other = read_object(s3, shard_key(s3, "swap", 2))
    key = shard_key(s3, "swap", 0)
    assert len(other) != len(read_object(s3, key))
    s3.client.put_object(Bucket=BUCKET, Key=key, Body=other)
    r = run("inspect", url, env=env, check=False)
    assert r.returncode != 0 and "shard 0" in r.stderr, r.stderr
    r = run("verify", url, "--dry-run", env=env, check=False)
    assert r.returncode == 1 and "shard 0: damaged" in r.stdout, r.stdout
    # run converts it again once; a second run has nothing to do.
    first = run("run", url, "--workers", "1", env=env)
    assert first.stderr.count("moved aside") == 1, first.stderr
    second = run("run", url, "--workers", "1", env=env)
    assert "moved aside" not in second.stderr, second.stderr
    assert status(url, env)["shards_done"] == 3
    assert digest(url, env) == clean
