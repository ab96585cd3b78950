"""Settings that follow the job (`sparc3d_vae.presets`), on real jobs converted by the binary:

- a job at N³ trains with `sparc3d_vae/configs/<N>.toml` unless `--config` says otherwise, says
  so on stderr and records it in config.json; a resolution without a file takes the largest
  measured one below it (the smallest above when none is below), jobs of several resolutions
  the finest's;
- `--config` keys win over the job's settings key by key;
- `--resume` keeps the run's settings with `--config`'s keys on top; `--init-from` keeps the
  source's `[model]` and takes the job's training settings;
- the files are package data (installed with the package) and `vae/configs` is the same files.
"""

import json
import pathlib

import pytest

import sparc3d_reader as reader
from sparc3d_vae import cli, infer, presets
from sparc3d_vae.config import load_config
from sparc3d_vae.runtime import load_checkpoint

ROOT = pathlib.Path(__file__).resolve().parents[2]


def run_cli(*args, capsys):
    code = cli.main([str(a) for a in args])
    return code, capsys.readouterr().err


def train(job, out, *args, capsys, steps=0):
    """`sparc3d-vae train` on CPU for `steps` steps; its exit code, stderr and config.json."""
    if not isinstance(job, (list, tuple)):
        job = [job]
    code, err = run_cli("train", "--data", *job, "--out", out, "--steps", steps,
                        "--device", "cpu", *args, capsys=capsys)
    written = json.loads((out / "config.json").read_text()) if code == 0 else None
    return code, err, written


def preset(n):
    """configs/<n>.toml as the package reads it, without the keys the job and the CLI set."""
    cfg = load_config(presets.CONFIG_DIR / f"{n}.toml").to_dict()
    cfg["model"].pop("deformation")
    cfg["train"].pop("steps")
    return cfg


def trained(written):
    """config.json's settings less the keys the job and the CLI set (as `preset`)."""
    cfg = {k: dict(written[k]) for k in ("model", "loss", "train")}
    cfg["model"].pop("deformation")
    cfg["train"].pop("steps")
    return cfg


@pytest.fixture(scope="module")
def job64(tmp_path_factory):
    from conftest import make_job

    return make_job(tmp_path_factory.mktemp("job64"), 64, ["sphere.obj"])


@pytest.fixture(scope="module")
def job128(tmp_path_factory):
    from conftest import make_job

    return make_job(tmp_path_factory.mktemp("job128"), 128, ["sphere.obj"])


@pytest.fixture(scope="module")
def run64(job64, tmp_path_factory):
    """Two steps on the 64³ job with no --config; the run folder and train's stderr."""
    out = tmp_path_factory.mktemp("run64") / "run"
    code = cli.main(["train", "--data", str(job64), "--out", str(out), "--steps", "2",
                     "--device", "cpu"])
    assert code == 0
    return out


def test_the_rule_for_resolutions_without_measured_settings():
    jobs = (32, 48, 64, 96, 127, 128, 200, 256, 1024)
    assert [presets.measured_for(n, [64, 128, 256]) for n in jobs] \
        == [64, 64, 64, 64, 64, 128, 128, 256, 256]
    assert sorted(presets.measured()) == [64, 128, 256]
    _, s = presets.for_jobs([96])
    assert (s.preset, s.file) == (64, "sparc3d_vae/configs/64.toml")
    assert "96³ has no measured settings: the largest measured resolution below it" in s.message()
    _, s = presets.for_jobs([32])
    assert s.preset == 64 and "the smallest measured resolution" in s.message()
    cfg, s = presets.for_jobs([])
    assert s.preset is None and cfg.to_dict() == load_config(None).to_dict()


def test_a_64_job_without_config_trains_with_the_64_settings(run64, job64, tmp_path, capsys):
    """The 64³ model (downsample 4: a 16³ latent grid), not the base N/16 (a 4³ grid)."""
    written = json.loads((run64 / "config.json").read_text())
    assert trained(written) == preset(64)
    assert written["model"]["downsample"] == 4 and written["train"]["ema_decay"] == 0.999
    assert written["settings"]["preset"] == 64
    assert written["settings"]["file"] == "sparc3d_vae/configs/64.toml"
    state = load_checkpoint(run64)
    assert state["step"] == 2 and state["config"]["model"] == written["model"]
    assert state["settings"] == written["settings"]
    # The latents of the trained model lie on the 16³ grid of a 64³ job at N/4.
    infer.encode(run64, [str(job64)], tmp_path / "latents", "cpu")
    coords = next(reader.iter_tensor_rows(tmp_path / "latents", infer.LATENT_TENSORS))["coords"]
    assert 64 // 8 <= coords.max() < 64 // 4, coords.max()
    # The line on stderr names the settings taken and how to change them.
    code, err, _ = train(job64, tmp_path / "again", capsys=capsys)
    assert code == 0
    assert "settings for 64³ jobs (sparc3d_vae/configs/64.toml); --config FILE to override" in err


def test_a_128_job_takes_the_128_settings_and_config_keys_win(job128, tmp_path, capsys):
    code, err, written = train(job128, tmp_path / "plain", capsys=capsys)
    assert code == 0, err
    assert trained(written) == preset(128) and written["settings"]["preset"] == 128
    assert written["train"]["max_cells_per_batch"] == 200_000 and written["train"]["lr"] == 0.0005
    assert "settings for 128³ jobs (sparc3d_vae/configs/128.toml)" in err
    over = tmp_path / "over.toml"
    over.write_text("[model]\nlatent_channels = 4\n[train]\nlr = 0.001\nbatch_size = 2\n")
    code, err, written = train(job128, tmp_path / "over", "--config", over, capsys=capsys)
    assert code == 0, err
    expected = preset(128)
    expected["model"]["latent_channels"] = 4
    expected["train"].update(lr=0.001, batch_size=2)
    assert trained(written) == expected  # every other key is 128.toml's
    assert written["settings"]["configs"] == [str(over)]
    assert f"settings for 128³ jobs (sparc3d_vae/configs/128.toml), then {over} on top" in err
    # A key that does not fit the job's settings: the error says what it was put on.
    clash = tmp_path / "clash.toml"
    clash.write_text("[model]\ndownsample = 8\n")
    code, err, _ = train(job128, tmp_path / "clash", "--config", clash, capsys=capsys)
    assert code == 2 and "on top of settings for 128³ jobs" in err and "model.channels" in err, err


def test_jobs_of_several_resolutions_or_an_unmeasured_one(job32, job64, job128, tmp_path, capsys):
    code, err, written = train([job64, job128], tmp_path / "both", capsys=capsys)
    assert code == 0, err
    assert written["settings"]["preset"] == 128 and trained(written) == preset(128)
    assert "the jobs are at 64³, 128³: the finest decides" in err
    assert written["settings"]["job_resolutions"] == [64, 128]
    code, err, written = train(job32, tmp_path / "r32", capsys=capsys)
    assert code == 0, err
    assert written["settings"]["preset"] == 64 and trained(written) == preset(64)
    assert "settings for 64³ jobs (sparc3d_vae/configs/64.toml; 32³ has no measured settings: " \
           "the smallest measured resolution)" in err


def test_resume_keeps_the_runs_settings_with_config_keys_on_top(job32, tmp_path, capsys):
    run = tmp_path / "run"
    assert train(job32, run, capsys=capsys, steps=1)[0] == 0
    code, err, written = train(job32, run, "--resume", capsys=capsys, steps=2)
    assert code == 0, err
    assert "resuming with the run's settings: settings for 64³ jobs" in err
    assert trained(written) == preset(64)
    # A file with only the keys to change: the others stay the run's (here 64.toml's rotations
    # and EMA, which the base defaults turn off).
    more = tmp_path / "more.toml"
    more.write_text("[train]\nlr = 0.001\n")
    code, err, written = train(job32, run, "--resume", "--config", more, capsys=capsys, steps=3)
    assert code == 0, err
    assert written["train"]["lr"] == 0.001 and written["train"]["augment_rotations"] is True
    assert written["settings"]["configs"] == [str(more)] and written["settings"]["preset"] == 64
    assert load_checkpoint(run)["step"] == 3
    other = tmp_path / "other.toml"
    other.write_text("[train]\nema_decay = 0.5\n")
    code, err, _ = train(job32, run, "--resume", "--config", other, capsys=capsys, steps=4)
    assert code == 2 and "train.ema_decay: 0.999 → 0.5" in err, err


def test_init_from_keeps_the_source_model_and_takes_the_jobs_training(run64, job64, job128,
                                                                       job32, tmp_path, capsys):
    # 128.toml is meant to continue a 64³ run: its [model] is 64.toml's, key for key.
    assert preset(128)["model"] == preset(64)["model"]
    source = load_checkpoint(run64)
    code, err, written = train(job128, tmp_path / "warm", "--init-from", run64, capsys=capsys)
    assert code == 0, err
    assert written["model"] == source["config"]["model"]
    assert written["train"] == {**preset(128)["train"], "steps": 0}
    assert written["settings"]["model_from"] == str(run64 / "checkpoint.pt")
    assert f"settings for 128³ jobs (sparc3d_vae/configs/128.toml) with the [model] of " \
           f"--init-from {run64 / 'checkpoint.pt'}" in err
    # A source whose [model] is not the job's measured one: its [model] wins (the weights
    # decide the network), the training settings are still the job's.
    small = tmp_path / "small.toml"
    small.write_text("[model]\nchannels = [8, 8, 16, 16]\nblocks = [0, 1, 1, 1]\ndownsample = 8\n"
                     "heads = 2\n[train]\nthreads = 1\n")
    assert train(job32, tmp_path / "src", "--config", small, capsys=capsys, steps=1)[0] == 0
    code, err, written = train(job64, tmp_path / "from_small", "--init-from", tmp_path / "src",
                               capsys=capsys, steps=1)
    assert code == 0, err
    assert written["model"]["downsample"] == 8 and written["model"]["channels"] == [8, 8, 16, 16]
    assert written["train"] == {**preset(64)["train"], "steps": 1}
    # --config may set [train] keys alone; a [model] key against the source's is refused.
    lr = tmp_path / "lr.toml"
    lr.write_text("[train]\nlr = 0.0001\n")
    code, err, written = train(job64, tmp_path / "lr", "--init-from", tmp_path / "src",
                               "--config", lr, capsys=capsys)
    assert code == 0 and written["train"]["lr"] == 0.0001 and written["model"]["downsample"] == 8
    wider = tmp_path / "wider.toml"
    wider.write_text("[model]\ndownsample = 4\nchannels = [8, 8, 16]\nblocks = [0, 1, 1]\n")
    code, err, _ = train(job64, tmp_path / "wider", "--init-from", tmp_path / "src", "--config",
                         wider, capsys=capsys)
    assert code == 2 and "model.downsample: 8 → 4" in err and "would not fit" in err, err


def test_the_measured_settings_are_package_data_and_vae_configs_holds_them():
    """`vae/configs/<N>.toml` (what older commands name) are the package's files; installed,
    the package carries the same files."""
    import importlib.metadata

    checkout = ROOT / "vae" / "sparc3d_vae" / "configs"
    names = sorted(f.name for f in checkout.glob("*.toml"))
    assert names == ["128.toml", "256.toml", "64.toml"]
    for name in names:
        assert (ROOT / "vae" / "configs" / name).resolve() == (checkout / name).resolve()
        assert (presets.CONFIG_DIR / name).read_bytes() == (checkout / name).read_bytes(), \
            f"the installed sparc3d_vae/configs/{name} differs from the checkout's: reinstall ./vae"
    if presets.CONFIG_DIR.resolve() == checkout.resolve():
        pytest.skip("sparc3d_vae runs from the checkout, not installed (`pip install ./vae`)")
    installed = {str(f) for f in importlib.metadata.distribution("sparc3d-vae").files}
    assert {f"sparc3d_vae/configs/{n}" for n in names} <= installed
