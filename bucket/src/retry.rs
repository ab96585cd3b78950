//! `retry` on a job in a bucket: a shard's rows to keep become a checkpoint of their own
//! (`state/part-NNNNN.journals/retry-<ms>.000000.journal`, created before anything else
//! changes), then the shard's older checkpoints, its record and its upload are deleted, so
//! the next `run` or `work` takes the shard, reads the kept rows from that checkpoint and
//! converts only the retried items. Killed in between, the shard is still finished (its
//! record is deleted last but one) or unfinished with its kept rows: `retry` can run again.

use crate::commit::read_record;
use crate::keys::{self, object_name};
use anyhow::{Context, Result};
use sparc3d_schema::ShardRow;
use sparc3d_sources::objects::{Prefix, WriteMode, Written};
use std::path::Path;

/// Makes shard `shard` unfinished with `kept` as its finished items.
pub fn requeue(
    prefix: &Prefix<'_>,
    shard: u64,
    fingerprint: &str,
    kept: &[ShardRow],
) -> Result<()> {
    let ms = sparc3d_workers::clock::since_epoch().as_millis();
    let key = keys::checkpoint(shard, &format!("retry-{ms}"), 0);
    let bytes =
        sparc3d_workers::journal::set::with_rows(Path::new(&key), shard, fingerprint, kept)?;
    let older = prefix.list(&keys::journals(shard))?;
    match prefix
        .put(&key, bytes, WriteMode::Create)
        .with_context(|| format!("writing {}", prefix.url(&key)))?
    {
        Written::Done(_) => {}
        Written::Refused => anyhow::bail!("{}: exists already", prefix.url(&key)),
    }
    for l in older {
        prefix.delete(&prefix.relative_key(&l))?;
    }
    if let Some(record) = read_record(prefix, shard)? {
        prefix.delete(&keys::record(shard))?;
        prefix.delete(&keys::data(&object_name(shard, &record)))?;
    }
    Ok(())
}
