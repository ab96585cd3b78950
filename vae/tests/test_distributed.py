"""Training on two processes (torchrun, gloo on CPU), as `torchrun --nproc_per_node N -m
sparc3d_vae train` runs it on several GPUs:

- the ranks' weights stay identical (each checkpoint records every rank's weight digest);
- a run is deterministic for a seed and a world size, also when stopped and resumed;
- a world size that does not divide the batch, and a checkpoint resumed with another world size
  or another config, are refused with one `error:` line naming the keys.
"""

import os
import socket
import subprocess
import sys

import pytest
import torch

from sparc3d_vae import cli, train
from sparc3d_vae.distributed import World, shard, weights_digest
from sparc3d_vae.runtime import load_checkpoint

TINY = """
[model]
channels = [8, 8, 16, 16]
blocks = [0, 1, 1, 1]
downsample = 8
heads = 2
[train]
batch_size = 2
threads = 1
checkpoint_every = 2
log_every = 1
"""


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def torchrun(*args, procs=2):
    """`python -m torch.distributed.run --nproc_per_node 2 -m sparc3d_vae ARGS` on this machine."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "OMP_NUM_THREADS": "1"}
    for k in ("RANK", "WORLD_SIZE", "LOCAL_RANK", "MASTER_ADDR", "MASTER_PORT"):
        env.pop(k, None)
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nnodes", "1",
           "--nproc_per_node", str(procs), "--master_addr", "127.0.0.1",
           "--master_port", str(free_port()), "-m", "sparc3d_vae", *map(str, args)]
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)


def test_batches_are_full_and_shared_by_rank():
    # 5 items, batches of 4: the stream runs on across epochs, every batch is full.
    seen = [train.batch_indices(s, 5, 4, seed=3) for s in range(5)]
    assert all(len(b) == 4 for b in seen)
    flat = sum(seen, [])
    for epoch in range(4):  # every epoch is a permutation of the items
        assert sorted(flat[5 * epoch:5 * epoch + 5]) == list(range(5))
    assert seen == [train.batch_indices(s, 5, 4, seed=3) for s in range(5)]
    batch = seen[0]
    parts = [shard(batch, World(r, r, 2)) for r in range(2)]
    assert sorted(parts[0] + parts[1]) == sorted(batch) and len(parts[0]) == len(parts[1]) == 2


@pytest.fixture(scope="module")
def two_process_runs(job32, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("ddp")
    config = tmp / "tiny.toml"
    config.write_text(TINY)
    common = ["--data", job32, "--config", config, "--device", "cpu"]
    straight = torchrun("train", *common, "--out", tmp / "straight", "--steps", 4)
    assert straight.returncode == 0, straight.stderr[-3000:]
    stopped = torchrun("train", *common, "--out", tmp / "stopped", "--steps", 2)
    assert stopped.returncode == 0, stopped.stderr[-3000:]
    resumed = torchrun("train", *common, "--out", tmp / "stopped", "--steps", 4, "--resume")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    return tmp, config


def test_two_ranks_keep_identical_weights(two_process_runs):
    tmp, _ = two_process_runs
    state = load_checkpoint(tmp / "straight")
    assert state["world_size"] == 2 and state["step"] == 4
    digests = state["rank_digests"]
    assert len(digests) == 2 and digests[0] == digests[1] == weights_digest(state["model"])
    # Training moved the weights: the zero-initialised last convolutions are no longer zero.
    assert any(float(v.abs().sum()) > 0 for k, v in state["model"].items() if "conv2.weight" in k)
    rows = (tmp / "straight" / "loss.csv").read_text().splitlines()
    assert len(rows) == 1 + 4  # rank 0 alone writes the log: a header and one row per step


def test_two_process_run_is_deterministic_and_resumable(two_process_runs):
    tmp, _ = two_process_runs
    a, b = load_checkpoint(tmp / "straight"), load_checkpoint(tmp / "stopped")
    assert a["step"] == b["step"] == 4
    for k, v in a["model"].items():
        assert torch.equal(v, b["model"][k]), k


def test_resume_with_another_world_size_or_config_is_refused(two_process_runs, job32, tmp_path,
                                                             capsys, monkeypatch):
    tmp, config = two_process_runs
    code = cli.main(["train", "--data", str(job32), "--out", str(tmp / "straight"), "--steps", "6",
                     "--resume", "--device", "cpu"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("error:") == 1, err
    assert "world size 2, resumed with 1" in err and "checkpoint.pt" in err
    # Same world size (as torchrun would tell the process), other batch size and width:
    # refused before the processes meet, naming both keys.
    other = tmp_path / "other.toml"
    other.write_text(TINY.replace("batch_size = 2", "batch_size = 4")
                     .replace("channels = [8, 8, 16, 16]", "channels = [8, 8, 16, 32]"))
    monkeypatch.setenv("WORLD_SIZE", "2")
    monkeypatch.setenv("RANK", "0")
    code = cli.main(["train", "--data", str(job32), "--out", str(tmp / "straight"), "--steps", "6",
                     "--resume", "--config", str(other), "--device", "cpu"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("error:") == 1, err
    assert "model.channels" in err and "train.batch_size" in err, err


def test_world_size_must_divide_the_batch(job32, tmp_path, capsys, monkeypatch):
    config = tmp_path / "tiny.toml"
    config.write_text(TINY.replace("batch_size = 2", "batch_size = 4"))
    for rank in ("0", "1"):
        monkeypatch.setenv("WORLD_SIZE", "3")
        monkeypatch.setenv("RANK", rank)
        code = cli.main(["train", "--data", str(job32), "--out", str(tmp_path / "run"),
                         "--config", str(config), "--steps", "1", "--device", "cpu"])
        err = capsys.readouterr().err
        assert code == 2
        if rank == "0":  # one line for the whole world: rank 0's
            assert err.count("error:") == 1 and "train.batch_size = 4" in err and "3 processes" in err, err
        else:
            assert "error:" not in err
    assert not (tmp_path / "run").exists()
