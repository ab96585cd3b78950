"""`StreamingDataset` (issue 44, item 4) on a job `sparc3d` converted: with 2 ranks x 2 real
DataLoader workers each item is received exactly once per epoch, the order changes with the
epoch and repeats for the same seed and epoch, `state_dict` / `load_state_dict` resume mid-epoch
with exactly the items not yet received (across an epoch change too), a job in a bucket (moto
on loopback) streams as its folder does, the shuffle buffer bounds what a worker holds, items
are the plain reader's, and a damaged shard is reported as the plain reader reports it."""

import json
import os
import shutil
import sys
import warnings

import numpy as np
import pyarrow.parquet as pq
import pytest
from torch.utils.data import get_worker_info

from remote_servers import s3_environment
from sparc3d_cli import ROOT
from stream_jobs import IDS, make_job

try:
    import sparc3d_reader as reader
except ImportError:  # not installed (`pip install ./python`): use the checkout
    if os.environ.get("SPARC3D_CI") == "1":
        raise
    sys.path.insert(0, str(ROOT / "python"))
    import sparc3d_reader as reader

from sparc3d_reader import streaming

BUFFER = 4


@pytest.fixture(scope="module")
def job(tmp_path_factory):
    return make_job(tmp_path_factory.mktemp("streaming"))


def tagged(batch):
    """Collate (in the worker): each item as (worker, id, rows the worker's dataset held at
    most so far)."""
    info = get_worker_info()
    return [(info.id if info else 0, it["id"], info.dataset.peak_held if info else 0)
            for it in batch]


def read(ds, workers=2, batch=3, stop=None):
    """(worker, id) of what a training loop receives through `ds.loader`, in order; with
    `stop`, it breaks off once it has that many items."""
    loader = ds.loader(batch_size=batch, num_workers=workers, collate_fn=tagged)
    got, batches = [], 0
    for b in loader:
        batches += 1
        assert all(peak <= ds.buffer_size for _, _, peak in b)
        got += [(w, i) for w, i, _ in b]
        if stop is not None and len(got) >= stop:
            return got
    assert batches == len(loader)
    return got


def dataset(job, rank=0, world=2, epoch=0, seed=7, **kw):
    ds = reader.StreamingDataset(job, seed=seed, rank=rank, world_size=world,
                                 buffer_size=BUFFER, **kw)
    ds.set_epoch(epoch)
    return ds


def ids(got):
    return [i for _, i in got]


def by_worker(got, w):
    return [i for x, i in got if x == w]


def test_two_ranks_two_workers_receive_each_item_once_per_epoch(job):
    orders = {}
    for epoch in (0, 1):
        ranks = []
        for rank in (0, 1):
            ds = dataset(job, rank, epoch=epoch)
            got = read(ds)
            sizes = ds.worker_sizes(2)
            assert [len(by_worker(got, w)) for w in (0, 1)] == sizes
            assert max(sizes) - min(sizes) <= 1
            assert ds.state_dict()["consumed"] == sizes  # the loader counted every batch
            assert len(got) == len(ds)
            ranks.append(ids(got))
        assert sorted(ranks[0] + ranks[1]) == IDS  # every item once, the failed row never
        assert abs(len(ranks[0]) - len(ranks[1])) <= 1
        orders[epoch] = ranks
    assert orders[0][0] + orders[0][1] != IDS  # shuffled
    assert orders[0][0] != orders[1][0] and orders[0][1] != orders[1][1]
    # The same seed and epoch: the same order, worker by worker; another seed: another.
    again = read(dataset(job, 1, epoch=1))
    assert ids(again) == orders[1][1]
    assert ids(read(dataset(job, 1, epoch=1, seed=8))) != orders[1][1]


def test_pad_and_drop_last_give_every_rank_as_many_items(job):
    padded = [ids(read(dataset(job, r, pad=True))) for r in (0, 1)]
    assert [len(p) for p in padded] == [12, 12]  # ceil(23 / 2)
    assert sorted(set(padded[0] + padded[1])) == IDS  # every item, one of them twice
    dropped = [ids(read(dataset(job, r, drop_last=True))) for r in (0, 1)]
    both = dropped[0] + dropped[1]
    assert [len(d) for d in dropped] == [11, 11] and len(set(both)) == 22
    with pytest.raises(ValueError, match="pad and drop_last"):
        dataset(job, pad=True, drop_last=True)


def test_items_are_the_plain_readers(job):
    plain = {it["id"]: it for it in reader.iter_items(job)}
    ds = reader.StreamingDataset(job, seed=1, rank=0, world_size=1)
    streamed = list(ds)
    assert sorted(it["id"] for it in streamed) == IDS and len(ds) == len(IDS)
    for it in streamed:
        want = plain[it["id"]]
        assert it.keys() == want.keys()
        for k, v in it.items():
            if isinstance(v, np.ndarray):
                assert v.dtype == want[k].dtype and np.array_equal(v, want[k]), (it["id"], k)
            else:
                assert v == want[k], (it["id"], k)


def resumed(state, job, rank, workers=2):
    """A new dataset at a saved state (saved as JSON: a plain dict)."""
    ds = dataset(job, rank)
    ds.load_state_dict(json.loads(json.dumps(state)))
    return ds


def test_resume_mid_epoch_and_across_an_epoch_change(job):
    want1 = read(dataset(job, 1, epoch=1), batch=2)
    want2 = read(dataset(job, 1, epoch=2), batch=2)
    ds = dataset(job, 1)
    read(ds, batch=2)  # all of epoch 0
    end_of_0 = ds.state_dict()
    ds.set_epoch(1)
    first = read(ds, batch=2, stop=5)  # three batches of epoch 1, then the run stops
    state = ds.state_dict()
    assert state["epoch"] == 1 and sum(state["consumed"]) == len(first) == 6

    again = resumed(state, job, 1)
    again.set_epoch(1)  # the top of the training loop: the position stays
    rest = read(again, batch=2)
    for w in (0, 1):  # each worker's share goes on exactly where it stopped
        assert by_worker(first, w) + by_worker(rest, w) == by_worker(want1, w)
    assert sorted(ids(first) + ids(rest)) == sorted(ids(want1))
    again.set_epoch(2)
    assert read(again, batch=2) == want2

    # Saved at the end of epoch 0: that epoch has nothing left, the next is whole.
    done = resumed(end_of_0, job, 1)
    assert read(done, batch=2) == []
    done.set_epoch(1)
    assert read(done, batch=2) == want1


def test_resume_without_workers_and_refusals(job):
    ds = reader.StreamingDataset(job, seed=5, where="license != by-nc")
    want = [it["id"] for it in ds]
    it = iter(ds)
    first = [next(it)["id"] for _ in range(7)]
    state = ds.state_dict()
    assert state["consumed"] == [7] and first == want[:7]
    again = reader.StreamingDataset(job, seed=5, where="license != by-nc")
    again.load_state_dict(state)
    assert [x["id"] for x in again] == want[7:]
    assert [x["id"] for x in again] == want  # a second pass of the epoch is whole
    for other, said in [(dict(seed=6, where="license != by-nc"), "seed"),
                        (dict(seed=5), "where"),
                        (dict(seed=5, where="license != by-nc", buffer_size=9), "buffer_size")]:
        with pytest.raises(ValueError, match=f"the state has {said}"):
            reader.StreamingDataset(job, **other).load_state_dict(state)
    fresh = dataset(job, 0, epoch=4).state_dict()  # nothing received: suits any workers
    assert fresh["consumed"] == [0]
    assert read(resumed(fresh, job, 0)) == read(dataset(job, 0, epoch=4))
    two = dataset(job, 0)
    read(two, stop=3)  # with two workers
    with pytest.raises(ValueError, match="2 DataLoader workers per rank, this iteration has 1"):
        read(resumed(two.state_dict(), job, 0), workers=0)
    with pytest.raises(ValueError, match="persistent_workers"):
        dataset(job).loader(num_workers=2, persistent_workers=True)


def test_the_buffer_bounds_what_is_held_and_decoding_waits_for_the_yield(job, monkeypatch):
    decoded = []
    decode = streaming.shard_item
    monkeypatch.setattr(streaming, "shard_item",
                        lambda path, row: decoded.append(row["id"]) or decode(path, row))
    ds = reader.StreamingDataset(job, seed=3, buffer_size=3)
    got = []
    for item in ds:
        got.append(item["id"])
        assert decoded == got  # one item decoded at a time, when it is yielded
        assert ds.peak_held <= 3
    assert ds.peak_held == 3 and sorted(got) == IDS
    # A buffer of one keeps the read order: the row groups in the epoch's shuffled order.
    plain = [it["id"] for it in reader.StreamingDataset(job, seed=3, buffer_size=1)]
    assert plain != got and plain != IDS
    assert [it["id"] for it in reader.StreamingDataset(job, shuffle=False)] == IDS


@pytest.fixture(scope="module")
def s3():
    """moto's S3 server, with this process's environment set to reach it."""
    with s3_environment() as server:
        yield server


def test_a_job_in_a_bucket_streams_as_its_folder(job, s3):
    for path in sorted(p for p in job.rglob("*") if p.is_file()):
        s3.put("stream", f"job/{path.relative_to(job)}", path.read_bytes())
    url = "s3://stream/job"
    for rank in (0, 1):
        assert read(dataset(url, rank, epoch=3)) == read(dataset(job, rank, epoch=3))
    ds = dataset(url, 0, epoch=3)
    first = read(ds, stop=4)
    rest = read(resumed(ds.state_dict(), url, 0))
    assert sorted(ids(first) + ids(rest)) == sorted(ids(read(dataset(job, 0, epoch=3))))


def test_a_damaged_shard_is_reported_as_the_plain_reader_reports_it(job, tmp_path):
    copy = tmp_path / "job"
    shutil.copytree(job, copy)
    path = copy / "shards" / "part-00002.parquet"
    data = bytearray(path.read_bytes())
    blob = pq.read_table(path, columns=["coords"]).column("coords")[0].as_py()
    at = data.find(blob)
    assert at > 0
    data[at + len(blob) // 2] ^= 0x10  # a byte of item 8's coords, same size
    path.write_bytes(bytes(data))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plain = [it["id"] for it in reader.iter_items(copy)]
        streamed = [it["id"] for it in reader.StreamingDataset(copy, shuffle=False)]
    said = [str(w.message) for w in caught if issubclass(w.category, reader.ShardWarning)]
    assert len(said) == 2 and said[0] == said[1] and f"{path} is not read" in said[0]
    assert streamed == plain == [i for i in IDS if i not in ("it08", "it09", "it10", "it11")]
    # Unverified, the damaged blob is found when decoded: the same error, naming the shard.
    with pytest.raises(ValueError) as plain_error:
        list(reader.iter_items(copy, verify=False))
    with pytest.raises(ValueError) as stream_error:
        list(reader.StreamingDataset(copy, verify=False, shuffle=False))
    assert str(stream_error.value) == str(plain_error.value)
    assert str(path) in str(plain_error.value)


def test_a_shard_replaced_after_opening_is_refused(job, tmp_path):
    copy = tmp_path / "job"
    shutil.copytree(job, copy)
    ds = reader.StreamingDataset(copy, shuffle=False)
    shutil.copy(copy / "shards" / "part-00002.parquet", copy / "shards" / "part-00001.parquet")
    got = []
    with pytest.raises(ValueError, match="part-00001.parquet changed since it was checked"):
        for it in ds:
            got.append(it["id"])
    assert got == IDS[:4]  # shard 0's items, then nothing of another shard under these rows
