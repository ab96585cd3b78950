"""`StreamingDataset.load_state_dict` takes only positions `state_dict()` could have written
(issue 64, item 9): an empty `consumed` (which replayed the whole epoch), counts and epochs that
`int()` turned into other positions (strings, 1.5, True), negative or float epochs, and a state
that is not a dict or lacks keys are each a `ValueError` naming what is wrong, as python/README
promises, and leave the dataset where it was. Iterated without DataLoader workers, so torch is
not needed."""

import json
import os
import sys

import pytest

from sparc3d_cli import ROOT
from stream_jobs import make_job

try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    if os.environ.get("SPARC3D_CI") == "1":
        raise
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    return make_job(tmp_path_factory.mktemp("stream_state"))


def saved(job, received=3):
    """A dataset and its state after `received` items of epoch 0 (saved as JSON: plain)."""
    ds = reader.StreamingDataset(job, seed=3)
    it = iter(ds)
    for _ in range(received):
        next(it)
    return json.loads(json.dumps(ds.state_dict()))


def ids(ds):
    return [x["id"] for x in ds]


def test_a_good_state_resumes_and_its_kinds_are_kept(job):
    state = saved(job)
    assert state["consumed"] == [3] and state["epoch"] == 0
    whole = ids(reader.StreamingDataset(job, seed=3))
    ds = reader.StreamingDataset(job, seed=3)
    ds.load_state_dict(state)
    assert ids(ds) == whole[3:]
    # A tuple of counts is the same list (torch.load of a state saved by an older pickle).
    ds.load_state_dict(dict(state, consumed=(3,)))
    assert ids(ds) == whole[3:]


@pytest.mark.parametrize("change, said", [
    ({"consumed": []}, r"consumed \[\]: it is a list of whole numbers"),
    ({"consumed": ["2"]}, r"consumed \['2'\]: it is a list"),
    ({"consumed": [1.5]}, r"consumed \[1.5\]: it is a list"),
    ({"consumed": [1.0]}, r"consumed \[1.0\]: it is a list"),
    ({"consumed": [True]}, r"consumed \[True\]: it is a list"),
    ({"consumed": [-1]}, r"consumed \[-1\]: it is a list"),
    ({"consumed": None}, "consumed None: it is a list"),
    ({"consumed": "3"}, "consumed '3': it is a list"),
    ({"consumed": {"0": 3}}, "consumed {'0': 3}: it is a list"),
    ({"epoch": -1}, "epoch -1: an epoch is a whole number 0 or more"),
    ({"epoch": -5}, "epoch -5: an epoch"),
    ({"epoch": 1e300}, "epoch 1e[+]300: an epoch"),
    ({"epoch": 1.5}, "epoch 1.5: an epoch"),
    ({"epoch": "1"}, "epoch '1': an epoch"),
    ({"epoch": True}, "epoch True: an epoch"),
    ({"epoch": None}, "epoch None: an epoch"),
    ({"epoch": 2**70}, "epoch 1180591620717411303424: an epoch"),
    ({"seed": 3.0}, "seed 3.0, this dataset 3"),
    ({"seed": "3"}, "seed '3', this dataset 3"),
    ({"shuffle": 1}, "shuffle 1, this dataset True"),
    ({"world_size": True}, "world_size True, this dataset 1"),
    ({"items": None}, "items None, this dataset 23"),
])
def test_a_position_that_is_not_ours_is_a_value_error_naming_it(job, change, said):
    state = saved(job)
    ds = reader.StreamingDataset(job, seed=3)
    with pytest.raises(ValueError, match="load_state_dict: the state has " + said):
        ds.load_state_dict(dict(state, **change))
    # Refused, the dataset is where it was: the whole epoch 0, counted from 0.
    assert ds.state_dict() == dict(state, consumed=[0])
    assert len(ids(ds)) == 23


@pytest.mark.parametrize("state, said", [
    (None, "a state is the dict state_dict[(][)] returned, got NoneType None"),
    ("epoch 0", "a state is the dict state_dict[(][)] returned, got str 'epoch 0'"),
    ([0, [3]], r"a state is the dict state_dict[(][)] returned, got list \[0, \[3\]\]"),
    ({}, "the state has no epoch, consumed, seed, rank, .*, digest [(]it holds nothing[)]"),
])
def test_a_state_that_is_not_a_dict_of_ours_is_a_value_error(job, state, said):
    with pytest.raises(ValueError, match="load_state_dict: " + said):
        reader.StreamingDataset(job, seed=3).load_state_dict(state)


@pytest.mark.parametrize("key", ["epoch", "consumed", "seed", "digest", "where"])
def test_a_missing_key_is_named(job, key):
    state = saved(job)
    del state[key]
    with pytest.raises(ValueError, match=f"load_state_dict: the state has no {key} [(]it holds "):
        reader.StreamingDataset(job, seed=3).load_state_dict(state)
