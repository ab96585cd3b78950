"""Bad input ends with one clear `error:` line naming the thing (exit status 2), not a stack
trace: a job of another schema version, an item with no active cells, a checkpoint of another
config, `--device cuda` without a GPU, a missing checkpoint; and every command has --help."""

import os
import pathlib
import subprocess
import sys

import numpy as np
import pyarrow.parquet as pq
import pytest
import torch

import sparc3d_reader as reader
from sparc3d_vae import cli
from sparc3d_vae.config import Config, ConfigError, load_config
from sparc3d_vae.data import DataError, to_sample
from sparc3d_vae.runtime import UsageError, pick_device

COMMANDS = ["train", "encode", "decode", "reconstruct", "evaluate"]


def run_cli(*args, capsys):
    code = cli.main([str(a) for a in args])
    return code, capsys.readouterr().err


@pytest.mark.parametrize("command", COMMANDS)
def test_every_command_has_help(command):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}  # the checkout, if not installed
    r = subprocess.run([sys.executable, "-m", "sparc3d_vae", command, "--help"],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0 and "usage: sparc3d-vae " + command in r.stdout


def test_job_of_another_schema_version(job32, tmp_path, capsys):
    src = reader.shard_paths(job32)[0]
    meta = dict(pq.ParquetFile(src).metadata.metadata)
    meta[b"sparc3d.schema_version"] = b"1"
    old = tmp_path / "part-00000.parquet"
    pq.write_table(pq.read_table(src).replace_schema_metadata(meta), old)
    code, err = run_cli("train", "--data", old, "--out", tmp_path / "run", "--steps", 1,
                        "--device", "cpu", capsys=capsys)
    assert code == 2 and "error:" in err and "schema version 1" in err and str(old) in err
    assert "Traceback" not in err


def test_item_without_active_cells_is_named(job32):
    item = next(reader.iter_items(job32))
    item["cells"] = item["cells"][:0]
    with pytest.raises(DataError, match=item["id"][:12] + ".*no active cells"):
        to_sample(item, deformation=False)


def test_checkpoint_of_another_config_is_refused(job32, tmp_path, capsys):
    small = tmp_path / "a.toml"
    small.write_text("[model]\nchannels = [8, 8, 16, 16]\nblocks = [0, 1, 1, 1]\ndownsample = 8\n"
                     "heads = 2\n[train]\nthreads = 1\n")
    other = tmp_path / "b.toml"
    other.write_text(small.read_text().replace("[8, 8, 16, 16]", "[8, 8, 16, 32]"))
    assert run_cli("train", "--data", job32, "--out", tmp_path / "run", "--config", small,
                   "--steps", 1, "--device", "cpu", capsys=capsys)[0] == 0
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "run", "--config", other,
                        "--steps", 2, "--resume", "--device", "cpu", capsys=capsys)
    assert code == 2 and "model.channels" in err and "[model] differs" in err, err
    # Without --resume an existing run is not overwritten.
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "run", "--steps", 1,
                        "--device", "cpu", capsys=capsys)
    assert code == 2 and "--resume" in err


def test_missing_or_foreign_checkpoint(job32, tmp_path, capsys):
    code, err = run_cli("encode", "--ckpt", tmp_path / "nothing.pt", "--data", job32,
                        "--out", tmp_path / "lat", "--device", "cpu", capsys=capsys)
    assert code == 2 and "nothing.pt" in err and "no checkpoint" in err
    junk = tmp_path / "junk.pt"
    torch.save({"weights": 1}, junk)
    code, err = run_cli("encode", "--ckpt", junk, "--data", job32, "--out", tmp_path / "lat",
                        "--device", "cpu", capsys=capsys)
    assert code == 2 and "not a sparc3d-vae checkpoint" in err


def test_cuda_device_without_a_gpu():
    if torch.cuda.is_available():
        assert pick_device("cuda").type == "cuda"
    else:
        with pytest.raises(UsageError, match="--device cuda: no CUDA device"):
            pick_device("cuda")
    assert pick_device("cpu").type == "cpu"


def test_config_file_matches_the_defaults_and_refuses_unknown_keys(tmp_path):
    documented = pathlib.Path(__file__).resolve().parents[1] / "vae.toml"
    assert load_config(documented).to_dict() == Config().to_dict()
    bad = tmp_path / "bad.toml"
    bad.write_text("[loss]\nsgn = 1.0\n")
    with pytest.raises(ConfigError, match="bad.toml: unknown key loss.sgn"):
        load_config(bad)
    bad.write_text("[model]\nchannels = [8, 8]\n")
    with pytest.raises(ConfigError, match="one per level"):
        load_config(bad)
    assert np.isclose(load_config(None).loss.kl, 1e-6)


def test_batches_over_the_cell_limit_are_split_and_large_items_refused_or_reported(job32, tmp_path, capsys, binary):
    from sparc3d_vae import infer, train
    from sparc3d_vae.train import split_parts

    samples = [to_sample(it, deformation=False) for it in reader.iter_items(job32)]
    small, big = sorted(samples, key=lambda s: len(s.cells))
    # Two items that do not fit together are two parts whose gradients add up.
    assert split_parts(samples, len(big.cells)) == [[0], [1]]
    assert split_parts(samples, len(big.cells) + len(small.cells)) == [[0, 1]]
    config = tmp_path / "limit.toml"
    config.write_text("[model]\nchannels = [8, 8, 16, 16]\nblocks = [0, 1, 1, 1]\n"
                      "downsample = 8\nheads = 2\n[train]\nthreads = 1\nbatch_size = 2\n"
                      f"max_cells_per_batch = {len(small.cells)}\n")
    summary = train.train([str(job32)], tmp_path / "run", config, 2, "cpu", resume=False)
    assert summary["skipped"] == {big.id: len(big.cells)}
    assert f"item {big.id!r} has {len(big.cells)} cells" in capsys.readouterr().err
    # Encoding cannot skip an item: it is refused, naming the item and the limit.
    code, err = run_cli("encode", "--ckpt", tmp_path / "run", "--data", job32,
                        "--out", tmp_path / "lat", "--device", "cpu", capsys=capsys)
    assert code == 2 and big.id in err and "max_cells_per_batch" in err and "--max-cells" in err, err
    # Inference keeps no gradients: `--max-cells` raises the budget and the same item encodes.
    code, err = run_cli("encode", "--ckpt", tmp_path / "run", "--data", job32, "--out",
                        tmp_path / "lat", "--device", "cpu", "--max-cells", len(big.cells), capsys=capsys)
    assert code == 0, err
    assert len(list(reader.iter_tensor_rows(tmp_path / "lat", ["mean"]))) == len(samples)
    code, err = run_cli("encode", "--ckpt", tmp_path / "run", "--data", job32, "--out",
                        tmp_path / "lat0", "--device", "cpu", "--max-cells", 0, capsys=capsys)
    assert code == 2 and "--max-cells 0" in err, err
    # Evaluating goes on past it: that item is reported with the reason, the other measured.
    summary = infer.evaluate(tmp_path / "run", [str(job32)], 2, 0, tmp_path / "eval", "cpu", binary)
    rows = {r["id"]: r for r in summary["items"]}
    assert f"{len(big.cells)} cells" in rows[big.id]["error"] and "--max-cells" in rows[big.id]["error"]
    assert "forward pass" not in rows[small.id].get("error", "")
    assert rows[small.id]["latent_voxels"] > 0 and rows[small.id]["true_cells"] == len(small.cells)
    assert summary["aggregate"]["failed"] >= 1


def test_gpu_out_of_memory_names_the_batch_and_the_budget_key(job32, tmp_path, capsys, monkeypatch):
    """A CUDA out-of-memory error (raised here by a stand-in loss: no GPU is needed) ends
    training with one line naming the step, the batch's cells and the key to lower."""
    from sparc3d_vae import train
    from sparc3d_vae.runtime import OutOfMemory

    def oom(*args, **kwargs):
        raise OutOfMemory("CUDA out of memory. Tried to allocate 2.00 GiB")

    monkeypatch.setattr(train, "vae_loss", oom)
    config = tmp_path / "c.toml"
    config.write_text("[model]\nchannels = [8, 8, 16, 16]\nblocks = [0, 1, 1, 1]\n"
                      "downsample = 8\nheads = 2\n[train]\nthreads = 1\nbatch_size = 2\n")
    cells = sum(len(to_sample(it, False).cells) for it in reader.iter_items(job32))
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "run", "--config", config,
                        "--steps", 1, "--device", "cpu", capsys=capsys)
    assert code == 2 and err.count("error:") == 1 and "Traceback" not in err, err
    assert f"{cells} cells" in err and "step 1" in err and "lower train.max_cells_per_batch" in err


def test_hold_out_leaves_out_the_items_evaluate_samples(job32, tmp_path, capsys):
    from sparc3d_vae import train
    from sparc3d_vae.infer import choose

    ids = list(reader.SparseCubesDataset(job32).ids)
    config = tmp_path / "c.toml"
    config.write_text("[model]\nchannels = [8, 8, 16, 16]\nblocks = [0, 1, 1, 1]\n"
                      "downsample = 8\nheads = 2\n[train]\nthreads = 1\nbatch_size = 1\n")
    for seed in (0, 1):
        held = choose(ids, 1, seed)
        seen = []
        real = train.make_batch

        def spy(samples, device):
            seen.extend(s.id for s in samples)
            return real(samples, device)

        train.make_batch = spy
        try:
            s = train.train([str(job32)], tmp_path / f"run{seed}", config, 4, "cpu", False,
                            hold_out=1, hold_out_seed=seed)
        finally:
            train.make_batch = real
        assert s["items"] == len(ids) - 1 and seen and held[0] not in seen
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "none", "--config", config,
                        "--hold-out", len(ids), "--steps", 1, "--device", "cpu", capsys=capsys)
    assert code == 2 and "leaves none" in err and "train.hold_out" in err


def test_per_resolution_configs_load_and_keep_a_latent_grid_of_at_least_8():
    """sparc3d_vae/configs/<N>.toml: valid configs, and none leaves fewer than 8 latent voxels
    per axis (a 4³ grid at 64³ doubled the unseen error, docs/VAE.md)."""
    folder = pathlib.Path(__file__).resolve().parents[1] / "sparc3d_vae" / "configs"
    files = sorted(folder.glob("*.toml"))
    assert files
    for f in files:
        cfg = load_config(f)
        assert int(f.stem) // cfg.model.downsample >= 8, f


def test_init_from_refuses_resume_another_model_and_another_deformation(job32, tmp_path, capsys):
    small = tmp_path / "a.toml"
    small.write_text("[model]\nchannels = [8, 8, 16, 16]\nblocks = [0, 1, 1, 1]\ndownsample = 8\n"
                     "heads = 2\n[train]\nthreads = 1\n")
    assert run_cli("train", "--data", job32, "--out", tmp_path / "src", "--config", small,
                   "--steps", 1, "--device", "cpu", capsys=capsys)[0] == 0
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "src", "--resume",
                        "--init-from", tmp_path / "src", "--device", "cpu", capsys=capsys)
    assert code == 2 and "--init-from" in err and "--resume" in err, err
    other = tmp_path / "b.toml"
    other.write_text(small.read_text().replace("[8, 8, 16, 16]", "[8, 8, 16, 32]"))
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "new", "--config", other,
                        "--init-from", tmp_path / "src", "--steps", 1, "--device", "cpu",
                        capsys=capsys)
    assert code == 2 and "model.channels" in err and "src" in err, err
    code, err = run_cli("train", "--data", job32, "--out", tmp_path / "new",
                        "--init-from", tmp_path / "nothing", "--device", "cpu", capsys=capsys)
    assert code == 2 and "nothing" in err and "no checkpoint" in err, err
    # A model without δ cannot start a run on a job that stores it.
    from conftest import make_job

    (tmp_path / "d").mkdir()
    deform = make_job(tmp_path / "d", 32, ["sphere.obj"], deform=True)
    code, err = run_cli("train", "--data", deform, "--out", tmp_path / "new",
                        "--init-from", tmp_path / "src", "--steps", 1, "--device", "cpu",
                        capsys=capsys)
    assert code == 2 and "deformation" in err and "--init-from" in err, err
    assert not (tmp_path / "new").exists()
