"""Which shard files are read, and the checks every file passes before its rows are used.

A path is a job folder or job URL (its own shards, `job_listing.py`, each checked against its
completion record, `records.py`, and its rows against the frozen manifest, `row_checks.py`), a
folder of shard files, or a single file. Every file is then checked for its schema version and
its row count, and errors of pyarrow or zstd while reading it are a ValueError naming it.
"""

from __future__ import annotations

import contextlib
import json
import os
import pathlib
from typing import Any, Dict, Iterable, Iterator, List, Optional, Union

import pyarrow as pa
import pyarrow.parquet as pq

from . import job_listing, jobs, location, records, row_checks
from .records import Verify
from .location import ObjectPath
from .schema import META_CONFIG, META_SCHEMA_VERSION, SCHEMA_VERSION

#: A local path, or a job URL (`s3://bucket/prefix`, `gs://…`, `az://…`) where a job is taken.
PathLike = Union[str, os.PathLike, ObjectPath]

#: Errors of pyarrow or zstd reading a damaged file.
READ_ERRORS = (OSError, pa.ArrowException, UnicodeDecodeError, OverflowError)


def shard_paths(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool = True,
                verify: Verify = True) -> List[Union[pathlib.Path, ObjectPath]]:
    """The shard files under `paths` that the reader reads, checked as `iter_items` checks them
    (docs/RELIABILITY.md, "The Python reader"). Each path is a job folder (its own shards with a
    completion record that the file matches, and every row its item; with `complete_only`
    false also shards without a record), a folder of shard files, or a file (read when it has
    no completion record beside it), or a job URL (its shards' objects, as `ObjectPath`s whose
    `str` is their URL). Shards left out are named in a `ShardWarning`.

    `verify`: True hashes every shard against its record's sha256 (as `sparc3d inspect`), "quick"
    only those whose size or stamp changed since recorded (as `sparc3d status`), False checks
    the size only."""
    return [s.path for s in all_shards(paths, complete_only) if usable(s, verify, keep_open=False)]


def usable_shards(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool,
                  verify: Verify) -> List[records.Shard]:
    """The shards under `paths` that pass `usable`, the others named in a `ShardWarning`; each
    job shard holds the file its checks opened, for its reader to take (`take_file`)."""
    return [s for s in all_shards(paths, complete_only) if usable(s, verify)]


def all_shards(paths: Union[PathLike, Iterable[PathLike]], complete_only: bool) -> List[records.Shard]:
    """The shards under `paths`, not yet checked against their records."""
    if isinstance(paths, (str, os.PathLike, ObjectPath)):
        paths = [paths]
    out: List[records.Shard] = []
    for p in paths:
        p = location.of(p)
        if isinstance(p, ObjectPath):
            out += job_listing.job_shards(jobs.open_job(p), complete_only)
        elif p.is_dir():
            job = jobs.job_of_folder(p)
            out += job_listing.job_shards(job, complete_only) if job else _folder_shards(p, complete_only)
        elif p.is_file():
            out.append(_file_shard(p))
        else:
            raise FileNotFoundError(f"{p}: neither a job folder nor a shard file")
    return out


def record_beside(path: pathlib.Path) -> pathlib.Path:
    """The completion record of the file `path` (`part-NNNNN.parquet` → `part-NNNNN.complete.json`)."""
    return path.with_name(path.name[: -len(".parquet")] + ".complete.json")


def _file_shard(path: pathlib.Path) -> records.Shard:
    """A file named on its own: a shard of a job (checked as the job's), or any other file."""
    job, index = jobs.job_of_file(path)
    record, torn = records.read_record(record_beside(path)) if path.suffix == ".parquet" else (None, None)
    return records.Shard(path, job, index, record, torn=torn)


def _folder_shards(folder: pathlib.Path, complete_only: bool) -> List[records.Shard]:
    """`part-*.parquet` of a folder outside a job (or its `shards/`): those with a completion
    record (all with `complete_only` false); no job to check names or rows against."""
    shards = folder / "shards" if (folder / "shards").is_dir() else folder
    out = []
    for f in sorted(shards.glob("part-*.parquet")):
        record, torn = records.read_record(record_beside(f))
        if record is not None or torn is not None or not complete_only:
            out.append(records.Shard(f, record=record, torn=torn))
    return out


def usable(shard: records.Shard, verify: Verify, keep_open: bool = True) -> bool:
    """Whether a shard is read: it matches its completion record as far as `verify` looks,
    and a job's shard holds its items (`row_checks.check_rows`). Otherwise a ShardWarning says
    why. A job's shard is opened for its footer and rows; with `keep_open` the shard holds that
    file until its reader takes it (`take_file`), else it is closed."""
    records.check_verify_mode(verify)
    why = shard.torn
    if why is None and shard.record is not None:
        why = records.check_against_record(shard, verify)
    if why is None and shard.job is not None:
        why = _rows_not_the_shards(shard, keep_open)
    if why is None:
        return True
    fix = (f" `sparc3d verify {shard.job.root}` moves it aside, `sparc3d run {shard.job.root}` "
           "converts it again." if shard.job else "")
    job_listing.warn_shards(f"{shard.path} is not read, its items left out: {why}.{fix}")
    return False


def _rows_not_the_shards(shard: records.Shard, keep_open: bool) -> Optional[str]:
    """Why a job shard's footer or rows are not its own (`row_checks.check_rows`), if so; a file
    pyarrow cannot read is damaged too. A shard that passes holds its open file when
    `keep_open`."""
    try:
        f = location.parquet_file(shard.path)
        why = row_checks.check_footer(shard, f) or row_checks.check_rows(
            shard, row_checks.read_check_columns(shard.path, f))
    except READ_ERRORS as e:
        return f"it cannot be read ({type(e).__name__}: {e})"
    if why is None and keep_open:
        shard.file = f
    return why


def take_file(shard: records.Shard) -> pq.ParquetFile:
    """The shard's Parquet file: the one `usable` opened to check it, handed over (the shard
    keeps no hold on it, so only the reader that reads it keeps it open), else opened now."""
    f, shard.file = shard.file, None
    return f if f is not None else location.parquet_file(shard.path)


def check_schema_version(path: PathLike) -> None:
    """Raises a ValueError naming the file when a shard (or tensor file) is of another schema
    version than this reader decodes."""
    path = location.of(path)
    check_version(path, location.parquet_file(path))


def check_version(path: location.Location, f: pq.ParquetFile) -> None:
    """`check_schema_version` of a file already opened."""
    meta = f.metadata.metadata or {}
    version = meta.get(META_SCHEMA_VERSION.encode(), b"missing").decode()
    if version != str(SCHEMA_VERSION):
        raise ValueError(f"{path}: shard schema version {version}, this reader decodes "
                         f"version {SCHEMA_VERSION} (docs/FORMAT.md)")


def shard_config(path: PathLike) -> Dict[str, Any]:
    """The job config a shard was written with (its `sparc3d.config` metadata); {} if absent."""
    meta = location.parquet_file(location.of(path)).metadata.metadata or {}
    raw = meta.get(META_CONFIG.encode())
    return json.loads(raw) if raw else {}


def read_job_config(job: PathLike) -> Dict[str, Any]:
    """The config of a job folder or job URL (`job.json`'s `config`)."""
    root = location.of(job)
    if isinstance(root, ObjectPath):
        location.require_job(root)
    return json.loads(location.read_text(root / "job.json"))["config"]


def check_row_count(path: location.Location, read: int, stored: int) -> None:
    """A ValueError naming the file when fewer (or more) rows were read than its footer says."""
    # pyarrow reads a column chunk whose page header is damaged as no rows at all, silently.
    if read != stored:
        raise ValueError(f"{path}: {read} rows read, its footer says {stored}: the file is "
                         "damaged (read it with verify=True to leave such a shard out)")


@contextlib.contextmanager
def naming(path: location.Location) -> Iterator[None]:
    """Errors of pyarrow or zstd reading a file (a damaged page, a blob failing zstd's checksum,
    text that is not UTF-8) as a ValueError naming the file."""
    try:
        yield
    except READ_ERRORS as e:
        raise ValueError(f"{path}: cannot be read ({type(e).__name__}: {e})") from e
