"""Which of a job's shards are read: `shards/part-NNNNN.parquet` for N below `job.json`'s
`shards`, or the object `shards/<object>` its record names, when its completion record parses
(and, unless `complete_only`, those without one). Every shard left out, and every other
`.parquet` in `shards/`, is named in a `ShardWarning`, with its quarantine folder when `run` or
`verify` moved it aside; in a bucket, uploads that no record names are left without a word.
"""

from __future__ import annotations

import os
import re
import sys
import warnings
from typing import TYPE_CHECKING, Dict, List

from . import location
from .location import ObjectPath
from .records import Shard, read_record

if TYPE_CHECKING:
    from .job_file import Job

#: A writer's upload of a shard's data to a bucket, `part-NNNNN.<token>.parquet`: the shard's
#: data when its record names it (`object`), else a leftover of a writer that lost the race for
#: the record or died before writing it.
_UPLOAD_NAME = re.compile(r"^part-(\d{5,})\.[^/\\]+\.parquet$")


class ShardWarning(UserWarning):
    """A shard of a job that is not read (not finished, damaged, quarantined) or a file in
    `shards/` that is not one of the job's shards; the message names it and says why."""


def job_shards(job: Job, complete_only: bool) -> List[Shard]:
    """The job's own shards that have a completion record that parses (and, unless
    `complete_only`, those without one), in order. Every other shard and every stray file in
    `shards/` is named in a ShardWarning. Records are not checked against files here
    (`records.check_against_record` does)."""
    out: List[Shard] = []
    notes: List[str] = []
    for i in range(job.shards):
        record, torn = read_record(job.record_file(i))
        path = job.shard_file(i)
        if record is not None:
            data, torn = job.data_file(i, record)
        if torn is not None:
            notes.append(f"{path.name}: damaged, {torn}")
        elif record is not None:
            out.append(Shard(data, job, i, record))
        elif complete_only or not location.exists(path):
            notes.append(f"{path.name}: not finished")
        else:
            out.append(Shard(path, job, i, None))
    _warn_not_read(job, notes, _quarantined(job))
    _warn_strays(job, {s.path.name for s in out})
    return out


def _quarantined(job: Job) -> Dict[str, List[str]]:
    """Shard name → its folders in `quarantine/` with the first line of their reason."""
    found: Dict[str, List[str]] = {}
    for d in location.entries(job.root / "quarantine"):
        name = d.name.rsplit("-", 1)[0]
        try:
            reason = location.read_text(d / "reason.txt", errors="replace").strip().splitlines()[0]
        except (OSError, IndexError):
            reason = "no reason.txt"
        found.setdefault(name, []).append(f"quarantine/{d.name} ({reason})")
    return found


def _warn_not_read(job: Job, notes: List[str], quarantined: Dict[str, List[str]]) -> None:
    if not notes:
        return
    lines = []
    for note in notes:
        name = note.split(".parquet", 1)[0]
        moved = quarantined.get(name)
        lines.append(note + (f"; moved aside to {', '.join(moved)}" if moved else ""))
    warn_shards(f"{job.root}: {len(notes)} of {job.shards} shards are not read, their items "
                f"left out: {'; '.join(lines)}. `sparc3d status {job.root}` shows the job; "
                f"`sparc3d run {job.root}` converts what is left")


def _warn_strays(job: Job, read: set) -> None:
    """Names every `.parquet` in `shards/` that is neither a shard's slot
    (`part-NNNNN.parquet`) nor read (`read`: the objects records name). In a bucket, writers'
    uploads that no record names (`part-NNNNN.<token>.parquet`) are left without a word: a
    writer that lost the race for a record, or died before writing it, leaves one."""
    own = {job.shard_file(i).name for i in range(job.shards)} | read
    bucket = isinstance(job.root, ObjectPath)
    strays = sorted(n for n in location.parquet_names(job.root / "shards")
                    if not n.startswith(".") and n not in own
                    and not (bucket and _UPLOAD_NAME.match(n)))
    if strays:
        last = job.shard_file(max(job.shards - 1, 0)).name
        warn_shards(f"{job.root}: ignored {', '.join(strays)} in shards/: not one of the "
                    f"job's {job.shards} shards (part-00000.parquet … {last})")


def warn_shards(message: str) -> None:
    """Issues a ShardWarning, attributed to the first caller outside this package."""
    package = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 2
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, ShardWarning, stacklevel=level)
