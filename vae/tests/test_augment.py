"""The 24 cube rotations used as augmentation are exact on the grid: checked against a dense
grid of the item's φ and δ rotated with numpy (transpose and flip), and as a group (24 distinct
rotations, four quarter turns about an axis give the item back)."""

import numpy as np
import pytest

import sparc3d_reader as reader
from sparc3d_vae.augment import ROTATIONS, Rotation, rotate_sample, rotation_for
from sparc3d_vae.data import to_sample

CORNERS = np.array([[(o >> 2) & 1, (o >> 1) & 1, o & 1] for o in range(8)])


@pytest.fixture(scope="module")
def item(tmp_path_factory):
    from conftest import make_job

    job = make_job(tmp_path_factory.mktemp("rot"), 16, ["wuson.stl"], deform=True)
    it = next(reader.iter_items(job))
    assert np.abs(it["deformation"]).max() > 0.01
    return it


def dense(item):
    """φ and δ on the dense (N + 1)³ vertex grid, NaN where a vertex is not stored."""
    n = item["resolution"] + 1
    phi = np.full((n, n, n), np.nan, np.float32)
    delta = np.full((n, n, n, 3), np.nan, np.float32)
    x, y, z = item["coords"].astype(np.int64).T
    phi[x, y, z] = item["sdf"]
    delta[x, y, z] = item["deformation"]
    return phi, delta


def rotate_dense(phi, delta, r):
    """Independent of `augment`: numpy's transpose and flip, δ's components moved along."""
    phi = np.transpose(phi, r.perm)
    delta = np.transpose(delta, (*r.perm, 3))[..., list(r.perm)]
    for axis, f in enumerate(r.flip):
        if f:
            phi = np.flip(phi, axis)
            delta = np.flip(delta, axis)
            delta[..., axis] *= -1
    return phi, delta


def test_the_24_rotations_form_the_rotation_group():
    mats = [r.matrix() for r in ROTATIONS]
    assert len({m.tobytes() for m in mats}) == 24
    assert all(round(np.linalg.det(m)) == 1 for m in mats)
    assert (mats[0] == np.eye(3)).all()
    keys = {m.tobytes() for m in mats}
    for a in mats:  # closed under composition
        for b in mats:
            assert (a @ b).tobytes() in keys


@pytest.mark.parametrize("index", range(24))
def test_rotated_features_match_the_rotated_grid(item, index):
    r = ROTATIONS[index]
    s = to_sample(item, deformation=True)
    rs = rotate_sample(s, r)
    phi, delta = rotate_dense(*dense(item), r)
    corners = rs.cells[:, None, :].astype(np.int64) + CORNERS[None]  # [C, 8, 3]
    x, y, z = corners[..., 0], corners[..., 1], corners[..., 2]
    assert not np.isnan(phi[x, y, z]).any()  # every rotated corner is a stored vertex
    np.testing.assert_array_equal(rs.feats[:, :8], phi[x, y, z])
    np.testing.assert_array_equal(rs.feats[:, 8:].reshape(-1, 8, 3), delta[x, y, z])
    assert len(np.unique(rs.cells, axis=0)) == len(s.cells)


def test_four_quarter_turns_give_the_item_back(item):
    s = to_sample(item, deformation=True)
    quarter = Rotation((0, 2, 1), (False, True, False))  # about x: y ← −z, z ← y
    assert quarter in ROTATIONS
    t = s
    for turn in range(4):
        t = rotate_sample(t, quarter)
        if turn < 3:
            assert not np.array_equal(np.sort(t.cells, axis=0), np.sort(s.cells, axis=0)) or \
                not np.array_equal(t.feats, s.feats)
    order_s = np.lexsort(s.cells.T[::-1])
    order_t = np.lexsort(t.cells.T[::-1])
    np.testing.assert_array_equal(t.cells[order_t], s.cells[order_s])
    np.testing.assert_array_equal(t.feats[order_t], s.feats[order_s])


def test_rotation_choice_is_a_function_of_seed_step_and_position():
    picks = [rotation_for(0, step, pos) for step in range(20) for pos in range(4)]
    assert picks == [rotation_for(0, step, pos) for step in range(20) for pos in range(4)]
    assert len(set(picks)) > 12  # spread over the group, not one rotation
