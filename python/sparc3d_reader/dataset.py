"""`SparseCubesDataset`: indexable items of jobs or shard files, a `torch.utils.data.Dataset`
when torch is installed (imported only when the class is first asked for)."""

from __future__ import annotations

import dataclasses
from typing import Any, Dict, Iterable, Iterator, List, Optional, Tuple, Union

import pyarrow as pa

from . import location, records
from .items import item_columns, shard_item
from .records import Verify
from .selection import bind_where, open_files, selected_rows
from .shards import PathLike, check_row_count, naming, usable_shards


class SparseCubesDatasetBase:
    """Indexable items of jobs / shard files (see `iter_items` for what an item holds).

    Checks the shards as `shard_paths` does (`verify`: True, "quick" or False; a shard that
    fails is left out with a `ShardWarning`) and indexes the `ok` rows once (metadata columns
    only); `ds[i]` reads the row group holding item i (the last one read is cached, so reading
    in order is cheap), after checking that its shard file was not changed since. `transform`,
    when given, is applied to each item. `where` keeps only the items that pass a filter on
    the scalar columns, in the language of the binary's `--where` (`where.py`)."""

    def __init__(self, paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
                 transform=None, verify: Verify = True, where: Optional[str] = None):
        shards = usable_shards(paths, complete_only, verify)
        self.paths = [s.path for s in shards]
        # Each shard with its record and stamp when checked, to notice a later change; without
        # its job (what DataLoader workers are sent stays small).
        self._shards = [dataclasses.replace(s, job=None) for s in shards]
        self.transform = transform
        #: The filter the items passed (`where.py`), as given.
        self.where = where
        # (shard number, row group, row within the group) of every ok row that passes.
        self.index: List[Tuple[int, int, int]] = []
        self.ids: List[str] = []
        files = open_files(shards)
        bound = bind_where(where, files)
        for s, (path, f) in enumerate(zip(self.paths, files)):
            for g in range(f.metadata.num_row_groups):
                rows, ids = selected_rows(path, f, g, bound)
                self.index += [(s, g, int(r)) for r in rows]
                self.ids += ids
        self._cache: Tuple[Optional[Tuple[int, int]], Optional[pa.Table]] = (None, None)

    def _row_group(self, s: int, g: int) -> pa.Table:
        """Row group `g` of shard file `s` (cached), once its file is known to be unchanged."""
        key, table = self._cache
        if key != (s, g) or table is None:
            path = self.paths[s]
            records.check_unchanged(self._shards[s])
            f = location.parquet_file(path)
            table = f.read_row_group(g, columns=item_columns(path, f, samples=True))
            check_row_count(path, table.num_rows, f.metadata.row_group(g).num_rows)
            self._cache = ((s, g), table)
        return table

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> Dict[str, Any]:
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"item {i} out of range ({len(self)} items)")
        s, g, r = self.index[i]
        with naming(self.paths[s]):
            row = self._row_group(s, g).slice(r, 1).to_pylist()[0]
        item = shard_item(self.paths[s], row)
        return self.transform(item) if self.transform else item

    def __iter__(self) -> Iterator[Dict[str, Any]]:
        for i in range(len(self)):
            yield self[i]

    def __getstate__(self):
        # Worker processes of a DataLoader get a copy without the cached row group. Shards in a
        # bucket are `ObjectPath`s (their URL only): a worker makes its filesystem again.
        state = self.__dict__.copy()
        state["_cache"] = (None, None)
        return state
