"""The model's plumbing on real items (the example meshes at 32³): the decoder under teacher
forcing rebuilds exactly the encoder's structure, perfect per-corner predictions written back
give the shard's own cubes, the loss targets match the data, and the model runs under bf16
autocast (on CPU here, standing in for CUDA)."""

import numpy as np
import pytest
import torch

import sparc3d_reader as reader
from sparc3d_vae.config import Config
from sparc3d_vae.data import corners_to_cubes, make_batch, to_sample
from sparc3d_vae.loss import child_targets, vae_loss
from sparc3d_vae.model import SparconvVAE


@pytest.fixture(scope="module")
def samples(job32):
    return [to_sample(it, deformation=False) for it in reader.iter_items(job32)]


def small_model(deformation=False):
    cfg = Config()
    cfg.model.channels, cfg.model.blocks, cfg.model.downsample = [8, 8, 16, 16], [0, 1, 1, 1], 8
    cfg.model.heads, cfg.model.deformation = 2, deformation
    torch.manual_seed(0)
    return cfg, SparconvVAE(cfg.model)


def test_perfect_predictions_write_back_the_shards_cubes(job32, samples):
    items = list(reader.iter_items(job32))
    x = make_batch(samples, torch.device("cpu"))
    phi = x.feats[:, :8]
    cubes = corners_to_cubes(x, (-phi).sign() * 10.0, phi.abs(), None)
    for it, c in zip(items, cubes):
        np.testing.assert_array_equal(c.cells, it["cells"].astype(np.uint16))
        np.testing.assert_array_equal(c.coords, it["coords"].astype(np.uint16))
        np.testing.assert_array_equal(c.sdf < 0, it["sdf"] < 0)
        np.testing.assert_allclose(np.abs(c.sdf), np.abs(it["sdf"]), atol=1e-4)


def test_teacher_forcing_follows_the_true_structure(samples):
    cfg, model = small_model()
    x = make_batch(samples, torch.device("cpu"))
    dec, mean, logvar, structure = model(x)
    assert [s.level for s in structure] == [0, 1, 2, 3]
    assert mean.level == 3 and mean.feats.shape[1] == cfg.model.latent_channels
    assert torch.equal(dec.cells.coords, x.coords)
    assert [p.level for p in dec.parents] == [3, 2, 1]
    for p in dec.parents:
        # Every true voxel has at least one true child; the targets say so.
        t = child_targets(p, structure[p.level - 1])
        assert (t.sum(dim=1) >= 1).all()
        assert int(t.sum()) == len(structure[p.level - 1].coords)


def test_decoder_prunes_to_what_it_predicts(samples):
    _, model = small_model()
    x = make_batch(samples, torch.device("cpu"))
    with torch.no_grad():
        mean, _, _ = model.encode(x)
        dec = model.decoder(mean, None)
    for p, logits, child in zip(dec.parents, dec.occ_logits, dec.parents[1:] + [dec.cells]):
        assert len(child.coords) == int((logits > 0).sum())


def test_runs_under_bf16_autocast(samples):
    cfg, model = small_model()
    x = make_batch(samples, torch.device("cpu"))
    with torch.autocast("cpu", dtype=torch.bfloat16):
        dec, mean, logvar, structure = model(x)
        loss, terms = vae_loss(dec, logvar, mean, structure, x.feats, cfg.loss)
    assert loss.dtype == torch.float32 and np.isfinite(terms["loss"])
    loss.backward()
    for name, p in model.named_parameters():
        assert p.grad is not None and p.grad.dtype == torch.float32, name
        assert torch.isfinite(p.grad).all(), name


def test_evaluate_samples_the_items_sparc3d_eval_samples(job32):
    """`sparc3d-vae evaluate --sample N --seed S` measures the items that
    `sparc3d eval JOB --sample N --sample-seed S` measures."""
    import json

    from sparc3d_cli import run
    from sparc3d_vae.infer import choose

    ids = list(reader.SparseCubesDataset(job32).ids)
    for seed in (0, 3):
        r = run("eval", job32, "--sample", 1, "--sample-seed", seed, "--samples", 1000, "--json")
        measured = [it["id"] for it in json.loads(r.stdout)["items"]]
        assert choose(ids, 1, seed) == measured
