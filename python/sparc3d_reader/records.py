"""One shard file against its completion record, as the CLI checks it (docs/RELIABILITY.md,
"Finished shards"): the record parses, has the job's fingerprint (another is an error: a mixed
job), is this shard's, and the file matches it: its size and sha256 (`verify=True`), its size
and stamp with the sha256 only when the stamp changed (`verify="quick"`; an object has no
stamp: it is hashed only when modified after its record was created), or its size only
(`verify=False`). A checked file that changes later is noticed (`check_unchanged`).
"""

from __future__ import annotations

import dataclasses
import json
import pathlib
from typing import TYPE_CHECKING, Dict, Optional, Tuple, Union

import pyarrow.parquet as pq

from . import location
from .location import Location, ObjectPath

if TYPE_CHECKING:
    from .job_file import Job

Verify = Union[bool, str]

#: The values of `verify`: True (or "full") hashes every shard, "quick" only those whose
#: stamp changed, False none.
VERIFY_MODES = (True, "full", "quick", False)


def check_verify_mode(verify: Verify) -> None:
    """A ValueError unless `verify` is one of VERIFY_MODES (1 and 0 are not)."""
    if not any(verify is m if isinstance(m, bool) else verify == m for m in VERIFY_MODES):
        raise ValueError(f"verify={verify!r}: one of True, 'full', 'quick', False")


@dataclasses.dataclass
class Shard:
    """A shard file to read: its job and index (None for a file outside a job), its completion
    record (None when it has none) and the file's stamp once checked, to notice a later change."""

    path: Location
    job: Optional[Job] = None
    index: Optional[int] = None
    record: Optional[dict] = None
    stamp: Optional[Tuple[int, int, int, int]] = None
    #: Why its completion record cannot be used (it does not parse), if so.
    torn: Optional[str] = None
    #: The file opened to check its footer and rows, until the reader that reads the rows
    #: takes it (`shards.take_file`): a shard is opened once on the way to its first row.
    #: Never copied (`dataclasses.replace`), compared or shown.
    file: Optional[pq.ParquetFile] = dataclasses.field(default=None, init=False, repr=False,
                                                       compare=False)


_stamp = location.stamp


def file_sha256(path: Location) -> str:
    """Hex sha256 of a file's (or an object's) bytes, read in 4 MiB blocks."""
    return location.sha256(path)


# Files that matched their record in this process, by path: (size, mtime, ctime, inode, sha256).
# A file whose stamp is unchanged since has not been written (the ctime cannot be set back), so
# opening the same job again, or its shard files one by one, hashes nothing twice. Objects are
# not remembered: their stamp (size and a time to the second) does not show every rewrite.
_verified: Dict[str, Tuple[int, int, int, int, str]] = {}


def read_record(path: Location) -> Tuple[Optional[dict], Optional[str]]:
    """The completion record at `path`: (None, None) when absent, (None, why) when it does
    not parse, else (record, None)."""
    try:
        text = location.read_bytes(path)
    except FileNotFoundError:
        return None, None
    try:
        record = json.loads(text)
        if not isinstance(record, dict):
            raise ValueError("not a JSON object")
        return record, None
    except ValueError as e:
        return None, f"its completion record {path} does not parse ({e})"


def check_against_record(shard: Shard, verify: Verify) -> Optional[str]:
    """None when the shard file matches its completion record as far as `verify` looks (and
    `shard.stamp` is set), else why not. A record with another config's fingerprint is a
    ValueError, as in the CLI."""
    job, record = shard.job, shard.record or {}
    if job is not None and record.get("fingerprint") != job.fingerprint:
        raise ValueError(
            f"{shard.path}: its completion record has fingerprint {record.get('fingerprint')}, "
            f"the job {job.root} has {job.fingerprint}: a shard of another config (configs are "
            "never mixed; use a new job folder)")
    if job is not None and record.get("shard") != shard.index:
        return f"its completion record is shard {record.get('shard')}'s"
    try:
        stamp = _stamp(shard.path)
    except FileNotFoundError:
        return f"{shard.path} is missing"
    if stamp[0] != record.get("bytes"):
        return f"{shard.path} has {stamp[0]} bytes, its completion record says {record.get('bytes')}"
    why = _check_sha(shard, stamp, verify)
    if why is None:
        shard.stamp = stamp
    return why


def _check_sha(shard: Shard, stamp: Tuple[int, int, int, int], verify: Verify) -> Optional[str]:
    record = shard.record or {}
    local = isinstance(shard.path, pathlib.Path)
    if verify is False or (local and _verified.get(str(shard.path)) == (*stamp, record.get("sha256"))):
        return None
    if verify == "quick" and _unchanged_since_record(shard, stamp):
        return None
    sha = file_sha256(shard.path)
    if sha != record.get("sha256"):
        return (f"{shard.path} has sha256 {sha}, its completion record says "
                f"{record.get('sha256')} (the file changed after it was written)")
    if local:
        _verified[str(shard.path)] = (*stamp, sha)
    return None


def _unchanged_since_record(shard: Shard, stamp: Tuple[int, int, int, int]) -> bool:
    """Whether the file is as its record found it, by what its store keeps: on disk the
    record's `stamp` (a record without one: no); in a bucket, where records have no stamp, the
    object not modified after its record was created, both times by the store's clock (a writer
    uploads its object, then creates the record). An object rewritten within the second its
    record was created passes; `verify=True` notices it."""
    if isinstance(shard.path, ObjectPath):
        if shard.job is None or shard.index is None:
            return False
        try:
            created = location.stamp(shard.job.record_file(shard.index))[1]
        except FileNotFoundError:
            return False
        return 0 < stamp[1] <= created
    recorded = (shard.record or {}).get("stamp") or {}
    return (recorded.get("modified_ns"), recorded.get("changed_ns"), recorded.get("inode")) == stamp[1:]


def check_unchanged(shard: Shard) -> None:
    """A ValueError when the shard file changed since it was checked (a `run` or `verify`
    replaced or moved it while a dataset was open). A file whose stamp changed but whose bytes
    still match its record (copied back, touched) is fine, as in the CLI's quick check."""
    if shard.stamp is None:
        return
    try:
        now: Optional[Tuple[int, int, int, int]] = _stamp(shard.path)
    except FileNotFoundError:
        now = None
    if now == shard.stamp:
        return
    why = "it is gone" if now is None or shard.record is None else check_against_record(shard, True)
    if why is not None:
        raise ValueError(f"{shard.path} changed since it was checked ({why}): its rows may "
                         "have moved; open the dataset again")
