"""Which shards of a job are read, checked the way the `sparc3d` CLI checks them
(docs/RELIABILITY.md, "Finished shards" and "The Python reader"). A job is a folder or a URL of
a bucket prefix (`location.py`); both are read by the same code.

A job's shards are `shards/part-NNNNN.parquet` for N below `job.json`'s `shards`, or the object
`shards/<object>` that the record names (writers to a bucket upload under names of their own).
One is read only when its completion record `part-NNNNN.complete.json` parses, has the job's
fingerprint (another is an error, as in the CLI: a mixed job), is this shard's, and the file
matches it: its size and sha256 (`verify=True`, what `inspect`/`show` do), or its size and stamp
with the sha256 only when the stamp changed (`verify="quick"`, what `run`/`status` do; an object
has no stamp: it is hashed only when modified after its record was created), or its size only
(`verify=False`). Its footer must name the job's fingerprint, and its rows are checked against
the frozen manifest before any is returned: one row per item of the shard, in order, with the
manifest's id and uri, a known status, as many ok rows as the record counts, the job's
resolution and a normalization the converter can produce.

A shard that is not read for any of these reasons, and any other `.parquet` file in `shards/`
(a stray `part-00099`), is named in a `ShardWarning`, with its quarantine folder when `run` or
`verify` moved it aside. In a bucket, `part-NNNNN.<token>.parquet` objects that no record names
are uploads of writers that lost a race or died before their record: not shards, not named. `warnings.simplefilter("error", ShardWarning)` makes them errors.

This module is where the names meet: the job itself is `job_file` (`Job`: job.json, its frozen
manifest and slices, `open_job`), and the checks are modules by role: `job_listing` (which
shards are read, `ShardWarning`), `records` (a shard against its completion record),
`row_checks` (its footer and rows against the frozen manifest). Each imports `Job` from
`job_file`, none from here.
"""

from __future__ import annotations

from .job_file import PAGE_SHARDS, Job, job_of_file, job_of_folder, open_job
from .job_listing import ShardWarning, job_shards, warn_shards
from .records import (VERIFY_MODES, Shard, Verify, check_against_record, check_unchanged,
                      check_verify_mode, file_sha256, read_record)
from .row_checks import CHECK_COLUMNS, check_footer, check_rows, read_check_columns, require_columns

__all__ = ["CHECK_COLUMNS", "Job", "PAGE_SHARDS", "Shard", "ShardWarning", "VERIFY_MODES",
           "Verify", "check_against_record", "check_footer", "check_rows", "check_unchanged",
           "check_verify_mode", "file_sha256", "job_of_file", "job_of_folder", "job_shards",
           "open_job", "read_check_columns", "read_record", "require_columns", "warn_shards"]
