//! Committing a shard to the bucket. The shard was written and committed in the worker's
//! scratch folder as on disk; then:
//!
//! 1. the lease is renewed (the fence), and the file is uploaded under a name of this
//!    writer's own (`shards/part-NNNNN.<writer>.parquet`), so that no upload ever replaces
//!    another's;
//! 2. the lease is renewed again, and the completion record, naming that object in its
//!    `object` field, is created only if no record is there: the first record wins, and a
//!    reader never sees a half shard (it reads only what a record names, and a record is
//!    written after its object's upload finished);
//! 3. once this writer's record is in place, the shard's checkpoints and the other writers'
//!    uploads (killed before their record, or losers of the race, which no record names and so
//!    no reader reads) are deleted, then the lease.
//!
//! A writer whose record lost the race deletes its own upload and reports the shard finished
//! elsewhere.

use crate::keys;
use crate::lease::BucketLease;
use anyhow::{bail, Context, Result};
use sparc3d_schema::{CompletionRecord, JobLayout};
use sparc3d_sources::objects::{Prefix, Version, WriteMode, Written};
use sparc3d_workers::store::commit::Committed;

/// Uploads shard `shard`, committed in the scratch job at `local` with `record`, and creates
/// its record in the bucket.
pub fn push(
    prefix: &Prefix<'_>,
    local: &JobLayout,
    shard: u64,
    record: &CompletionRecord,
    writer: &str,
    lease: &BucketLease,
) -> Result<Committed> {
    let name = keys::data_name(shard, writer);
    let fence = |step: &str| {
        lease
            .confirm()
            .map_err(|why| anyhow::anyhow!("shard {shard}: not {step}: {why}"))
    };
    fence("uploaded")?;
    let file = local.shard_file(shard);
    prefix
        .upload(&keys::data(&name), &file)
        .with_context(|| format!("uploading shard {shard}"))?;
    let object_etag = uploaded_etag(prefix, shard, &name)?;
    fence("committed")?;
    let in_bucket = CompletionRecord {
        stamp: None,
        object: Some(name.clone()),
        object_etag,
        ..record.clone()
    };
    let bytes = serde_json::to_vec_pretty(&in_bucket)?;
    let record_key = keys::record(shard);
    match prefix
        .put(&record_key, bytes, WriteMode::Create)
        .with_context(|| format!("writing the completion record of shard {shard}"))?
    {
        Written::Done(_) => {
            clean_up(prefix, shard, &name);
            Ok(Committed::Done(in_bucket))
        }
        Written::Refused => {
            let _ = prefix.delete(&keys::data(&name));
            match read_record(prefix, shard)? {
                Some(theirs) => Ok(Committed::FinishedElsewhere(theirs)),
                None => bail!(
                    "shard {shard}: its record was refused as existing, then could not be read"
                ),
            }
        }
    }
}

/// The ETag of the upload `name` of `shard` as a HEAD request shows it, the same request
/// [`crate::integrity::check_object`] makes later (so that a store whose listings spell ETags
/// otherwise than its uploads' replies cannot make every later check fail).
fn uploaded_etag(prefix: &Prefix<'_>, shard: u64, name: &str) -> Result<Option<String>> {
    let key = keys::data(name);
    match prefix
        .head(&key)
        .with_context(|| format!("shard {shard}: looking up its upload"))?
    {
        Some(found) => Ok(found.etag),
        None => bail!(
            "shard {shard}: {} is not there after its upload",
            prefix.url(&key)
        ),
    }
}

/// The completion record of `shard` in the bucket, if there is one; a record that does not
/// parse is an error naming it.
pub fn read_record(prefix: &Prefix<'_>, shard: u64) -> Result<Option<CompletionRecord>> {
    Ok(read_record_version(prefix, shard)?.map(|(record, _)| record))
}

/// [`read_record`] with the record object's version, for a write that replaces exactly it.
pub fn read_record_version(
    prefix: &Prefix<'_>,
    shard: u64,
) -> Result<Option<(CompletionRecord, Version)>> {
    let key = keys::record(shard);
    let Some(found) = prefix
        .get(&key)
        .with_context(|| format!("reading {}", prefix.url(&key)))?
    else {
        return Ok(None);
    };
    let record = serde_json::from_slice(&found.bytes)
        .with_context(|| format!("{}: not a completion record", prefix.url(&key)))?;
    Ok(Some((record, found.version)))
}

/// After this writer's record is in place: its checkpoints and every other upload of the
/// shard go (best effort: a leftover is never read, and the next commit of a shard has
/// nothing to do with it).
fn clean_up(prefix: &Prefix<'_>, shard: u64, kept: &str) {
    if let Ok(found) = prefix.list(&keys::journals(shard)) {
        for l in found {
            let _ = prefix.delete(&prefix.relative_key(&l));
        }
    }
    let mine = format!("{}{}.", keys::SHARDS, JobLayout::shard_name(shard));
    if let Ok(found) = prefix.list_starting(&mine) {
        for l in found {
            let key = prefix.relative_key(&l);
            let name = key.trim_start_matches(keys::SHARDS);
            if name.ends_with(".parquet") && name != kept {
                let _ = prefix.delete(&key);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lease::tests::memory_prefix;
    use crate::lease::{acquire, Acquired};
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    fn record(bytes: &[u8]) -> CompletionRecord {
        crate::integrity::tests::record(bytes, None)
    }

    /// Two writers of one shard (the second one's lease taken after the first lost it): the
    /// first record wins, the loser's upload is deleted, a leftover upload is cleaned up.
    #[test]
    fn the_first_record_wins_and_no_upload_is_left_but_its_own() -> Result<()> {
        let prefix = memory_prefix();
        let dir = tempfile::tempdir()?;
        let local = JobLayout::new(dir.path());
        std::fs::create_dir_all(local.shards_dir())?;
        std::fs::write(local.shard_file(0), b"shard bytes of writer a")?;
        prefix.put(
            "shards/part-00000.ghost.parquet",
            b"killed".to_vec(),
            WriteMode::Overwrite,
        )?;
        let lease = |owner: &str| match acquire(
            &prefix,
            0,
            owner,
            60.0,
            Arc::new(AtomicBool::new(false)),
        ) {
            Ok(Acquired::Held(l)) => l,
            other => panic!("lease not taken: {other:?}"),
        };
        let a = lease("a");
        let first = push(
            &prefix,
            &local,
            0,
            &record(b"shard bytes of writer a"),
            "a",
            &a,
        )?;
        a.release();
        let Committed::Done(done) = first else {
            panic!("the first writer commits")
        };
        assert_eq!(done.object.as_deref(), Some("part-00000.a.parquet"));
        std::fs::write(local.shard_file(0), b"writer b")?;
        let b = lease("b");
        let second = push(&prefix, &local, 0, &record(b"writer b"), "b", &b)?;
        b.release();
        assert!(matches!(second, Committed::FinishedElsewhere(r) if r.object == done.object));
        let uploads: Vec<String> = prefix
            .list(keys::SHARDS)?
            .iter()
            .map(|l| prefix.relative_key(l))
            .filter(|k| k.ends_with(".parquet"))
            .collect();
        assert_eq!(uploads, vec!["shards/part-00000.a.parquet".to_string()]);
        assert_eq!(read_record(&prefix, 0)?, Some(done));
        Ok(())
    }
}
