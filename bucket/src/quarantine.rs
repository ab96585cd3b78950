//! A damaged shard of a job in a bucket moved aside, as `verify` and `run` do on disk: its
//! record and the upload it names (when it is there) are copied under
//! `quarantine/part-NNNNN-<ms>/` with a `reason.txt` (nothing is lost), then the record is
//! deleted (the shard is unfinished again, and the next `run` or `work` converts it), then the
//! upload, which no record names any more. The caller holds the shard's lease (`verify`, or
//! the worker about to convert the shard again).

use crate::commit::read_record;
use crate::keys::{self, object_name};
use anyhow::{Context, Result};
use sparc3d_schema::JobLayout;
use sparc3d_sources::objects::{Prefix, WriteMode};

/// Moves shard `shard` aside for `reason`; returns the URL of its quarantine folder, or
/// `None` when it has no record (nothing to move).
pub fn quarantine(prefix: &Prefix<'_>, shard: u64, reason: &str) -> Result<Option<String>> {
    let Some(record) = read_record(prefix, shard)? else {
        return Ok(None);
    };
    let ms = sparc3d_workers::clock::since_epoch().as_millis();
    let folder = format!("quarantine/{}-{ms}/", JobLayout::shard_name(shard));
    let name = object_name(shard, &record);
    let record_key = keys::record(shard);
    let record_name = record_key.trim_start_matches(keys::SHARDS);
    let moved = |what: &str| format!("moving shard {shard}'s {what} into {folder}");
    prefix
        .copy(&record_key, &format!("{folder}{record_name}"))
        .with_context(|| moved("record"))?;
    if prefix.size(&keys::data(&name))?.is_some() {
        prefix
            .copy(&keys::data(&name), &format!("{folder}{name}"))
            .with_context(|| moved("data"))?;
    }
    prefix
        .put(
            &format!("{folder}reason.txt"),
            format!("{reason}\n").into_bytes(),
            WriteMode::Overwrite,
        )
        .with_context(|| moved("reason"))?;
    prefix
        .delete(&record_key)
        .with_context(|| moved("record"))?;
    prefix
        .delete(&keys::data(&name))
        .with_context(|| moved("data"))?;
    Ok(Some(prefix.url(&folder).to_string()))
}
