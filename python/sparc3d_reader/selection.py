"""Which rows of the shards the datasets read: the `ok` rows that pass a `where` filter
(`where.py`), found from the scalar columns alone, row group by row group, so that choosing
items never decodes a tensor."""

from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

import numpy as np
import pyarrow.parquet as pq

from . import location, records, row_checks
from .shards import check_row_count, naming, take_file
from .where import BoundWhere, Where


def open_files(shards: Sequence[records.Shard]) -> List[pq.ParquetFile]:
    """Each shard's file: the one its checks opened, else opened now (so its footer is read
    once), pyarrow's errors naming the file."""
    files = []
    for shard in shards:
        with naming(shard.path):
            files.append(take_file(shard))
    return files


def bind_where(where: Optional[str], files: Sequence[pq.ParquetFile]) -> Optional[BoundWhere]:
    """The filter `where` (None: none) parsed and checked against the shards' columns."""
    if where is None:
        return None
    return Where.parse(where).bind([f.schema_arrow for f in files])


def selected_rows(path: location.Location, f: pq.ParquetFile, group: int,
                  where: Optional[BoundWhere]) -> Tuple[np.ndarray, List[str]]:
    """The rows (positions within row group `group`, ascending) of the `ok` items that pass
    `where`, and their ids; reads `id`, `status` and the filter's columns only."""
    wanted = ["id", "status"] + (where.columns(f.schema_arrow) if where else [])
    row_checks.require_columns(path, f.schema_arrow.names, ["id", "status"])
    with naming(path):
        t = f.read_row_group(group, columns=list(dict.fromkeys(wanted)))
    check_row_count(path, t.num_rows, f.metadata.row_group(group).num_rows)
    status = t.column("status").to_pylist()
    keep = where.keep(t) if where else [True] * t.num_rows
    rows = [r for r, (s, k) in enumerate(zip(status, keep)) if s == "ok" and k]
    ids = t.column("id").to_pylist()
    return np.asarray(rows, dtype=np.int64), [ids[r] for r in rows]
