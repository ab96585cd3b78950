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


def test_siblings_structure_holds_every_child_of_the_true_parents(samples):
    """`train.structure = "siblings"`: the last level holds the 8 children of every true parent;
    the loss reads φ at a decoded cell's corners wherever that vertex is a true cell's corner."""
    from sparc3d_vae.loss import corner_targets

    cfg, model = small_model()
    x = make_batch(samples, torch.device("cpu"))
    dec, mean, logvar, structure = model(x, siblings=True)
    assert len(dec.cells.coords) == 8 * len(structure[1].coords)
    true_keys = set(x.keys.tolist())
    got = dec.cells.keys.tolist()
    assert true_keys <= set(got) and len(got) > len(true_keys)
    known, phi, _ = corner_targets(x, x.feats, dec.cells)
    # At the true cells every corner is known and equals the input.
    is_true = torch.tensor([k in true_keys for k in got])
    assert bool(known[is_true].all())
    order = {k: i for i, k in enumerate(x.keys.tolist())}
    rows = torch.tensor([order[k] for k in np.array(got)[is_true.numpy()]])
    assert torch.equal(phi[is_true], x.feats[rows, :8])
    # A sibling that is not a true cell shares some corners with true cells (known, with that
    # vertex's φ), and has some far corners (unknown).
    assert bool(known[~is_true].any()) and not bool(known[~is_true].all())
    dense = {}
    for c, f in zip(x.coords.tolist(), x.feats[:, :8].tolist()):
        for o in range(8):
            dense[(c[0], c[1] + (o >> 2 & 1), c[2] + (o >> 1 & 1), c[3] + (o & 1))] = f[o]
    for c, kn, ph in list(zip(dec.cells.coords.tolist(), known.tolist(), phi.tolist()))[:2000]:
        for o in range(8):
            v = (c[0], c[1] + (o >> 2 & 1), c[2] + (o >> 1 & 1), c[3] + (o & 1))
            assert kn[o] == (v in dense)
            if kn[o]:
                assert ph[o] == dense[v]
    loss, terms = vae_loss(dec, logvar, mean, structure, x.feats, cfg.loss)
    loss.backward()
    assert np.isfinite(terms["sign"]) and terms["sign"] > 0


def test_finest_conv_starts_as_the_identity_and_learns(samples):
    cfg, plain = small_model()
    cfg.model.finest_conv = 4
    torch.manual_seed(0)
    fine = SparconvVAE(cfg.model)
    assert fine.decoder.fine.conv.weight.shape == (27, 8, 4)  # 3×3×3 at full resolution
    missing = fine.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert missing and all(k.startswith("decoder.fine.") for k in missing)
    x = make_batch(samples, torch.device("cpu"))
    torch.manual_seed(1)
    a = plain(x, sample=False)[0]
    dec, mean, logvar, structure = fine(x, sample=False)
    assert torch.equal(a.sign_logits, dec.sign_logits)  # the zero-initialised projection
    loss, _ = vae_loss(dec, logvar, mean, structure, x.feats, cfg.loss)
    loss.backward()
    assert float(fine.decoder.fine.out.weight.grad.abs().sum()) > 0
