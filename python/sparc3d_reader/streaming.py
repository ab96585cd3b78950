"""`StreamingDataset`: a job's items streamed into training, a `torch.utils.data.IterableDataset`
when torch is installed (imported only when the class is first asked for).

The order is a pure function of (seed, epoch, rank, worker) (`stream_order.py`): every rank and
DataLoader worker computes its own share of the epoch without talking to the others, each item
is yielded exactly once per epoch across all of them, and a resumed run replays its order and
skips the items it had yielded. Memory is bounded: each worker holds at most `buffer_size`
rows read and not yet yielded (still encoded, as stored: their tensors are decoded one at a
time, when yielded) plus the batch of rows pyarrow is reading (`_READ_BATCH` rows of one row
group), never the job.
"""

from __future__ import annotations

import bisect
import dataclasses
import hashlib
import numbers
from collections.abc import Mapping
from typing import Any, Dict, Iterable, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np
import pyarrow.parquet as pq

from . import location, records, stream_order
from .items import item_columns, shard_item
from .records import Verify
from .selection import bind_where, open_files, selected_rows
from .shards import PathLike, check_row_count, naming, usable_shards

#: Rows pyarrow decodes at a time from a row group (the plain reader reads 16).
_READ_BATCH = 32

#: What `load_state_dict` requires to be the same as when the state was saved.
_SAME = ("seed", "rank", "world_size", "shuffle", "buffer_size", "pad", "drop_last", "where",
         "items", "digest")


class StreamingDatasetBase:
    """The `ok` items of a job (a folder or a job URL, `s3://bucket/prefix`, ...) streamed:
    `shuffle`d per epoch by `seed` and `set_epoch(e)` (row groups in a shuffled order, then a
    shuffle buffer of `buffer_size` items per worker), split exactly across `world_size` ranks
    (default: torch.distributed's when it is initialized, else 1) and the DataLoader workers of
    each, resumable mid-epoch with `state_dict()` / `load_state_dict()`.

    Shards are checked as `iter_items` checks them (`verify`, `complete_only`; a shard left
    out is named in a ShardWarning) and every item is decoded and checked as `iter_items`
    does (a ValueError names the shard). `where` keeps only the items passing a filter on the
    scalar columns (`where.py`), chosen from those columns alone before any tensor is read.

    Every item is yielded once per epoch, ranks' counts differing by at most one (workers'
    too). For DDP, where every rank must take as many steps, `pad=True` repeats the first
    items of the epoch's order until every rank has ceil(N / world_size), as
    `DistributedSampler` does, or `drop_last=True` leaves out the last N mod world_size.

    With DataLoader workers, read it through `ds.loader(...)`: a DataLoader that tells the
    dataset which worker each batch came from, so that `state_dict()` counts what the training
    loop received (workers read ahead). Iterated directly, the dataset counts what it yields."""

    def __init__(self, job_or_url: Union[PathLike, Iterable[PathLike]], seed: int = 0,
                 rank: Optional[int] = None, world_size: Optional[int] = None,
                 shuffle: bool = True, buffer_size: int = 256, where: Optional[str] = None,
                 pad: bool = False, drop_last: bool = False, transform=None,
                 samples: bool = True, complete_only: bool = True, verify: Verify = True):
        self.rank, self.world_size = _place(rank, world_size)
        _check_options(buffer_size, pad, drop_last)
        self.seed, self.shuffle, self.buffer_size = int(seed), bool(shuffle), int(buffer_size)
        self.where, self.pad, self.drop_last = where, bool(pad), bool(drop_last)
        self.transform, self.samples = transform, samples
        shards = usable_shards(job_or_url, complete_only, verify)
        self.paths = [s.path for s in shards]
        # Each shard with its record and stamp when checked (a later change is refused),
        # without its job: what DataLoader workers are sent stays small.
        self._shards = [dataclasses.replace(s, job=None) for s in shards]
        self._index(open_files(shards))
        self.epoch = 0
        self._consumed: List[int] = [0]  # items received this epoch, per worker
        self._pending: Optional[List[int]] = None  # a loaded position, until iterated
        self._iter_skip: Optional[List[int]] = None  # the position this iteration starts at
        self._started: List[int] = [0]  # and kept, for `start_position`
        self._tracked = False  # iterated through `loader()`, which counts per worker
        self._file: Tuple[Optional[int], Optional[pq.ParquetFile]] = (None, None)
        #: The most rows held read and not yet yielded at once, in this process.
        self.peak_held = 0

    def _index(self, files: Sequence[pq.ParquetFile]) -> None:
        """The selected items by row group (blocks): their shard and row group, their rows, and
        a digest of their ids (a saved state is for these items only)."""
        bound = bind_where(self.where, files)
        blocks, rows = [], []
        digest = hashlib.sha256()
        for s, (path, f) in enumerate(zip(self.paths, files)):
            for g in range(f.metadata.num_row_groups):
                selected, ids = selected_rows(path, f, g, bound)
                if len(selected):
                    blocks.append((s, g))
                    rows.append(selected)
                    digest.update("\n".join(ids).encode() + b"\n")
        self._blocks: List[Tuple[int, int]] = blocks
        self._block_sizes = np.array([len(r) for r in rows], dtype=np.int64)
        # Item number → its block and its row within the block's row group.
        self._item_block = np.repeat(np.arange(len(blocks), dtype=np.int32), self._block_sizes)
        self._item_row = (np.concatenate(rows) if rows else np.zeros(0, np.int64)).astype(np.int32)
        self._digest = digest.hexdigest()

    @property
    def items(self) -> int:
        """How many items the job has that pass `where` (all ranks together)."""
        return len(self._item_row)

    def __len__(self) -> int:
        """How many items this rank yields per epoch."""
        n = self.items
        if self.pad:
            return -(-n // self.world_size)
        if self.drop_last:
            return n // self.world_size
        lo, hi = stream_order.span(n, self.rank, self.world_size)
        return hi - lo

    def set_epoch(self, epoch: int) -> None:
        """Chooses the epoch whose order the next iteration yields; another epoch than the
        current one starts at its beginning, the current one keeps a position loaded by
        `load_state_dict` (so `set_epoch` at the top of a resumed training loop is right)."""
        if int(epoch) < 0:
            raise ValueError(f"set_epoch({epoch}): an epoch is 0 or more")
        if int(epoch) != self.epoch:
            self.epoch, self._pending, self._consumed = int(epoch), None, [0]

    # --- the order ---------------------------------------------------------------------------

    def _rank_items(self) -> np.ndarray:
        order = stream_order.epoch_order(self._block_sizes, self.seed, self.epoch, self.shuffle)
        return stream_order.rank_items(order, self.rank, self.world_size, self.pad, self.drop_last)

    def worker_sizes(self, workers: int) -> List[int]:
        """How many items each of `workers` DataLoader workers of this rank yields per epoch."""
        n = len(self)
        return [hi - lo for lo, hi in (stream_order.span(n, w, workers) for w in range(workers))]

    # --- iteration ---------------------------------------------------------------------------

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        """This rank's items of the epoch (in a DataLoader worker, that worker's share), from
        a loaded position when there is one."""
        worker, workers = _worker()
        if worker is None:  # the main process: it counts what it yields
            if self._iter_skip is None:
                self._begin(1)
            skip, self._iter_skip = (self._iter_skip or [0])[0], None
            for item in self._stream(0, 1, skip):
                self._consumed[0] += 1
                yield item
            return
        if not self._tracked and worker == 0:
            _warn_untracked()
        start = self._iter_skip or self._pending_for(workers) or [0] * workers
        yield from self._stream(worker, workers, start[worker])

    def _stream(self, worker: int, workers: int, skip: int) -> Iterator[Dict[str, Any]]:
        """Worker `worker`'s items of this epoch after the first `skip`, decoded when yielded."""
        mine = self._rank_items()
        lo, hi = stream_order.span(len(mine), worker, workers)
        positions = mine[lo:hi]
        order = stream_order.worker_order(len(positions), self.shuffle, self.buffer_size,
                                          self.seed, self.epoch, self.rank, worker)
        wanted = np.zeros(len(positions), dtype=bool)
        wanted[order[skip:]] = True
        held: Dict[int, Tuple[int, Dict[str, Any]]] = {}
        nxt = skip
        for start, end in _runs(self._item_block[positions], self._item_row[positions]):
            if not wanted[start:end].any():
                continue
            for p, row in self._read_run(positions, start, end, wanted):
                held[p] = row
                self.peak_held = max(self.peak_held, len(held))
                while nxt < len(order) and order[nxt] in held:
                    yield self._decode(*held.pop(int(order[nxt])))
                    nxt += 1

    def _read_run(self, positions: np.ndarray, start: int, end: int,
                  wanted: np.ndarray) -> Iterator[Tuple[int, Tuple[int, Dict[str, Any]]]]:
        """The rows of positions start..end (one row group, rows ascending) that are wanted,
        as (position, (shard, row)), read `_READ_BATCH` rows at a time."""
        s, g = self._blocks[self._item_block[positions[start]]]
        need = {int(self._item_row[positions[p]]): p for p in range(start, end) if wanted[p]}
        rows, path, i, offset = sorted(need), self.paths[s], 0, 0
        records.check_unchanged(self._shards[s])
        with naming(path):
            f = self._open(s)
            columns = item_columns(path, f, self.samples)
            for batch in f.iter_batches(batch_size=_READ_BATCH, row_groups=[g], columns=columns):
                j = bisect.bisect_left(rows, offset + batch.num_rows, i)
                if j - i == batch.num_rows:  # every row of the batch: no copy
                    picked = batch
                else:
                    picked = batch.take([r - offset for r in rows[i:j]])
                for r, row in zip(rows[i:j], picked.to_pylist() if j > i else []):
                    yield need[r], (s, row)
                i, offset = j, offset + batch.num_rows
                if i == len(rows):
                    return
        check_row_count(path, offset, f.metadata.row_group(g).num_rows)

    def _open(self, s: int) -> pq.ParquetFile:
        """Shard file `s`, opened once while its rows are read."""
        if self._file[0] != s or self._file[1] is None:
            self._file = (s, location.parquet_file(self.paths[s]))
        return self._file[1]

    def _decode(self, s: int, row: Dict[str, Any]) -> Dict[str, Any]:
        """The row as an item, checked as `iter_items` checks it (errors name the shard)."""
        with naming(self.paths[s]):
            item = shard_item(self.paths[s], row)
        return self.transform(item) if self.transform else item

    # --- position ----------------------------------------------------------------------------

    def _begin(self, workers: int) -> None:
        """Starts an iteration with `workers` workers: at a loaded position, else at the start."""
        start = self._pending_for(workers) or [0] * workers
        self._pending, self._iter_skip, self._consumed = None, list(start), list(start)
        self._started = list(start)

    def start_position(self, workers: int) -> List[int]:
        """The items of each worker's share skipped at the start of the next iteration (a
        loaded position), or of the iteration under way."""
        if self._pending is not None:
            return list(self._pending_for(workers) or [])
        return list(self._started) if len(self._started) == workers else [0] * workers

    def _pending_for(self, workers: int) -> Optional[List[int]]:
        """The loaded position for `workers` workers (an epoch's start suits any number)."""
        if self._pending is not None and not any(self._pending):
            return [0] * workers
        if self._pending is not None and len(self._pending) != workers:
            raise ValueError(f"the state loaded was saved reading with {len(self._pending)} "
                             f"DataLoader workers per rank, this iteration has {workers}: "
                             "resume with as many (num_workers=0 counts as one)")
        return self._pending

    def _received(self, worker: int, n: int) -> None:
        """`n` more items of worker `worker` reached the training loop (`loader()`)."""
        self._consumed[worker] += n

    def state_dict(self) -> Dict[str, Any]:
        """Where this rank is in the epoch: the items each DataLoader worker's share has given
        to the training loop, with what the order depends on (a plain dict, for torch.save)."""
        consumed = self._pending if self._pending is not None else self._consumed
        return {**self._config(), "epoch": self.epoch, "consumed": list(consumed)}

    def load_state_dict(self, state: Dict[str, Any]) -> None:
        """Resumes at a saved position: the next iteration of its epoch yields exactly the
        items not yet yielded then. A ValueError names what differs (seed, rank, world size,
        filter, the job's items, ...) or what is not a position of ours (a key missing, an
        epoch or a count that is not a whole number 0 or more, no count at all): a state is
        only valid for the same order, and nothing in it is converted."""
        epoch, consumed = _checked_state(state, self._config())
        sizes = self.worker_sizes(len(consumed))
        if any(not 0 <= c <= n for c, n in zip(consumed, sizes)):
            raise ValueError(f"load_state_dict: consumed {consumed} is not within {sizes}")
        self.epoch, self._pending, self._consumed = epoch, consumed, list(consumed)

    def _config(self) -> Dict[str, Any]:
        return {"seed": self.seed, "rank": self.rank, "world_size": self.world_size,
                "shuffle": self.shuffle, "buffer_size": self.buffer_size, "pad": self.pad,
                "drop_last": self.drop_last, "where": self.where, "items": self.items,
                "digest": self._digest}

    def loader(self, **kwargs):
        """A `torch.utils.data.DataLoader` over this dataset (the same arguments) that reports
        each batch's worker to it, so `state_dict()` is exact with workers."""
        from .stream_loader import streaming_loader

        return streaming_loader(self, **kwargs)

    def __getstate__(self):
        # Workers get a copy without the open file (a bucket's is made again there).
        state = self.__dict__.copy()
        state["_file"] = (None, None)
        return state


#: The largest epoch or count a state may hold (what a training loop could reach).
_MOST = 2**63 - 1


def _whole(v: Any) -> bool:
    """A whole number 0..`_MOST` as saved (an int, or a numpy integer): never a bool, a float
    or a string, which `int()` would turn into another position without a word."""
    return isinstance(v, numbers.Integral) and not isinstance(v, (bool, np.bool_)) \
        and 0 <= v <= _MOST


def _same_value(saved: Any, mine: Any) -> bool:
    """`saved` is `mine` as `state_dict` wrote it: equal, and of its kind (True is not seed 1,
    7.0 is not seed 7, "7" not either)."""
    if isinstance(mine, bool):
        return isinstance(saved, (bool, np.bool_)) and bool(saved) == mine
    if isinstance(mine, int):
        return isinstance(saved, numbers.Integral) and not isinstance(saved, (bool, np.bool_)) \
            and int(saved) == mine
    return type(saved) is type(mine) and saved == mine


def _checked_state(state: Any, mine: Dict[str, Any]) -> Tuple[int, List[int]]:
    """(epoch, consumed per worker) of a state `state_dict()` returned for a dataset with
    config `mine`; a ValueError naming what is missing, differs or is not a position."""
    said = "load_state_dict: "
    if not isinstance(state, Mapping):
        raise ValueError(f"{said}a state is the dict state_dict() returned, got "
                         f"{type(state).__name__} {_short(state)}")
    missing = [k for k in ("epoch", "consumed", *_SAME) if k not in state]
    if missing:
        raise ValueError(f"{said}the state has no {', '.join(missing)} (it holds "
                         f"{', '.join(map(str, state)) or 'nothing'}): not a state that "
                         "StreamingDataset.state_dict() returned")
    for key in _SAME:
        if not _same_value(state[key], mine[key]):
            raise ValueError(f"{said}the state has {key} {_short(state[key])}, this dataset "
                             f"{mine[key]!r}; a state resumes the same order only")
    epoch = state["epoch"]
    if not _whole(epoch):
        raise ValueError(f"{said}the state has epoch {_short(epoch)}: an epoch is a whole "
                         "number 0 or more")
    consumed = state["consumed"]
    if not isinstance(consumed, (list, tuple)) or not consumed \
            or not all(_whole(c) for c in consumed):
        raise ValueError(f"{said}the state has consumed {_short(consumed)}: it is a list of "
                         "whole numbers 0 or more, the items received from each DataLoader "
                         "worker's share (one for num_workers=0)")
    return int(epoch), [int(c) for c in consumed]


def _short(v: Any) -> str:
    """`repr(v)`, cut to 80 characters (a state may hold anything)."""
    r = repr(v)
    return r if len(r) <= 80 else r[:77] + "..."


def _runs(blocks: np.ndarray, rows: np.ndarray) -> Iterator[Tuple[int, int]]:
    """Spans of positions in one block with rows ascending (one read of a row group each)."""
    cut = np.flatnonzero((blocks[1:] != blocks[:-1]) | (rows[1:] <= rows[:-1])) + 1
    bounds = [0, *cut.tolist(), len(blocks)]
    return ((a, b) for a, b in zip(bounds, bounds[1:]) if b > a)


def _place(rank: Optional[int], world_size: Optional[int]) -> Tuple[int, int]:
    """(rank, world size): as given, else torch.distributed's when initialized, else (0, 1)."""
    if rank is None and world_size is None:
        try:
            import torch.distributed as dist

            if dist.is_available() and dist.is_initialized():
                return dist.get_rank(), dist.get_world_size()
        except ImportError:
            pass
        return 0, 1
    if rank is None or world_size is None:
        raise ValueError(f"rank={rank}, world_size={world_size}: give both or neither")
    if not 0 <= int(rank) < int(world_size):
        raise ValueError(f"rank={rank}, world_size={world_size}: a rank is 0..world_size-1")
    return int(rank), int(world_size)


def _check_options(buffer_size: int, pad: bool, drop_last: bool) -> None:
    if int(buffer_size) < 1:
        raise ValueError(f"buffer_size={buffer_size}: at least 1 (1 keeps the read order)")
    if pad and drop_last:
        raise ValueError("pad and drop_last: one or the other (equal counts either way)")


def _worker() -> Tuple[Optional[int], int]:
    """(this DataLoader worker's id, how many there are), or (None, 1) outside a worker."""
    try:
        from torch.utils.data import get_worker_info
    except ImportError:
        return None, 1
    info = get_worker_info()
    return (None, 1) if info is None else (info.id, info.num_workers)


def _warn_untracked() -> None:
    import warnings

    warnings.warn("StreamingDataset read by DataLoader workers outside `ds.loader(...)`: the "
                  "split and order are exact, but state_dict() cannot see what the training "
                  "loop received; use ds.loader(...) to resume mid-epoch", UserWarning)
