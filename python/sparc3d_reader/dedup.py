"""One item per near-duplicate group, from what `sparc3d dedup JOB --json` prints.

    import subprocess
    from sparc3d_reader import iter_items, one_per_group

    result = subprocess.run(["sparc3d", "dedup", "job", "--json"], check=True,
                            capture_output=True).stdout
    for item in one_per_group(iter_items("job"), result):
        ...                      # each group's representative, and every item of no group

The result is taken as the parsed object, its JSON text (`str` or `bytes`) or the path of a
file holding it; its `dropped` list names the ids `--one-per-group` leaves out (every group
member but the representative), as `sparc3d ls/export --one-per-group` do.
"""

from __future__ import annotations

import json
import os
import pathlib
from typing import Any, Dict, FrozenSet, Iterable, Iterator, Union

DedupResult = Union[Dict[str, Any], str, bytes, "os.PathLike[str]"]


def _parsed(result: DedupResult) -> Dict[str, Any]:
    if isinstance(result, dict):
        return result
    if isinstance(result, bytes):
        return json.loads(result)
    if isinstance(result, str) and result.lstrip().startswith("{"):
        return json.loads(result)
    return json.loads(pathlib.Path(result).read_text())


def dropped_ids(result: DedupResult) -> FrozenSet[str]:
    """The ids one item per group leaves out, from a `sparc3d dedup --json` result."""
    parsed = _parsed(result)
    dropped = parsed.get("dropped") if isinstance(parsed, dict) else None
    if not isinstance(dropped, list) or not all(isinstance(i, str) for i in dropped):
        raise ValueError("not the output of `sparc3d dedup --json`: no `dropped` list of ids")
    return frozenset(dropped)


def one_per_group(items: Iterable[Dict[str, Any]], result: DedupResult) -> Iterator[Dict[str, Any]]:
    """The items (e.g. of `iter_items`) whose id the dedup result does not leave out."""
    dropped = dropped_ids(result)
    return (item for item in items if item["id"] not in dropped)
