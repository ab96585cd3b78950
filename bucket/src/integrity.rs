//! Whether a finished shard of a job in a bucket is still what its completion record says.
//!
//! Two checks, as on disk (docs/RELIABILITY.md, "Jobs in a bucket"):
//! - [`object_mismatch`], cheap: the object the record names is there, with the recorded
//!   size and the ETag recorded when it was committed (`object_etag`; records of older
//!   versions have none, and only the size is compared). What a listing or one HEAD request
//!   shows; `status`, `run` and the local view of the read-only commands use it.
//! - [`hash_object`], full: the object read whole from the bucket and its sha256 compared with
//!   the record's; `verify` uses it, always.

use crate::commit::read_record;
use crate::keys::{self, object_name};
use anyhow::{Context, Result};
use sparc3d_schema::CompletionRecord;
use sparc3d_sources::list::Listed;
use sparc3d_sources::objects::Prefix;

/// Why the object `found` (as a listing or a HEAD request shows it; `None`: not there) is
/// not the one `record` of `shard` names, or `None` when it is, as far as its size and ETag
/// tell.
pub fn object_mismatch(
    shard: u64,
    record: &CompletionRecord,
    found: Option<&Listed>,
) -> Option<String> {
    let name = object_name(shard, record);
    let Some(found) = found else {
        return Some(format!(
            "its object shards/{name} is missing from the bucket"
        ));
    };
    if found.size != record.bytes {
        return Some(format!(
            "its object shards/{name} has {} bytes, its record says {}",
            found.size, record.bytes
        ));
    }
    match (&found.etag, &record.object_etag) {
        (Some(now), Some(then)) if now != then => Some(format!(
            "its object shards/{name} was replaced after its record was made (ETag {now}, \
             recorded {then})"
        )),
        _ => None,
    }
}

/// [`object_mismatch`] for the object in the bucket now (one HEAD request).
pub fn check_object(
    prefix: &Prefix<'_>,
    shard: u64,
    record: &CompletionRecord,
) -> Result<Option<String>> {
    let key = keys::data(&object_name(shard, record));
    let found = prefix
        .head(&key)
        .with_context(|| format!("shard {shard}: looking up {}", prefix.url(&key)))?;
    Ok(object_mismatch(shard, record, found.as_ref()))
}

/// A shard's completion record in the bucket, checked cheaply against its object.
#[derive(Debug, Clone, PartialEq)]
pub enum Finished {
    /// No record: the shard is not finished.
    No,
    /// The record, its object there as recorded.
    Done(Box<CompletionRecord>),
    /// A record whose object is missing, of another size or replaced: why.
    Damaged(String),
}

/// Reads `shard`'s record and checks its object ([`check_object`]).
pub fn finished(prefix: &Prefix<'_>, shard: u64) -> Result<Finished> {
    let Some(record) = read_record(prefix, shard)? else {
        return Ok(Finished::No);
    };
    Ok(match check_object(prefix, shard, &record)? {
        None => Finished::Done(Box::new(record)),
        Some(why) => Finished::Damaged(why),
    })
}

/// What [`hash_object`] found.
#[derive(Debug, Clone, PartialEq)]
pub enum Hashed {
    /// The object's bytes are the recorded ones; its ETag when read.
    Good {
        /// The ETag of the object read (quotes removed).
        etag: Option<String>,
    },
    /// What is wrong: the object is missing, or its size or sha256 differ from the record.
    Damaged(String),
}

/// Reads the object `record` of `shard` names from the bucket and hashes it (its bytes are
/// not kept).
pub fn hash_object(prefix: &Prefix<'_>, shard: u64, record: &CompletionRecord) -> Result<Hashed> {
    let name = object_name(shard, record);
    let key = keys::data(&name);
    let Some(got) = prefix
        .hash(&key)
        .with_context(|| format!("shard {shard}: reading {}", prefix.url(&key)))?
    else {
        return Ok(Hashed::Damaged(format!(
            "its object shards/{name} is missing from the bucket"
        )));
    };
    if got.bytes != record.bytes {
        return Ok(Hashed::Damaged(format!(
            "its object shards/{name} has {} bytes, its record says {}",
            got.bytes, record.bytes
        )));
    }
    if got.sha256 != record.sha256 {
        return Ok(Hashed::Damaged(format!(
            "its object shards/{name} has sha256 {}, its record says {} (it changed after it \
             was committed)",
            got.sha256, record.sha256
        )));
    }
    Ok(Hashed::Good { etag: got.etag })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::lease::tests::memory_prefix;
    use sha2::{Digest, Sha256};
    use sparc3d_sources::objects::WriteMode;

    /// The record of shard 0 whose data `bytes` are the object `part-00000.w.parquet` with
    /// ETag `etag`.
    pub(crate) fn record(bytes: &[u8], etag: Option<&str>) -> CompletionRecord {
        CompletionRecord {
            schema_version: sparc3d_schema::SCHEMA_VERSION,
            fingerprint: "fp".into(),
            rows: 1,
            ok: 1,
            bytes: bytes.len() as u64,
            sha256: sparc3d_schema::job::config::hex(&Sha256::digest(bytes)),
            object: Some("part-00000.w.parquet".into()),
            object_etag: etag.map(str::to_string),
            ..Default::default()
        }
    }

    /// A missing object, one of another size, one replaced by bytes of the same size (another
    /// ETag) and one flipped in place: the cheap check sees the first three, the hash all.
    #[test]
    fn missing_resized_replaced_and_flipped_objects_are_told_apart() -> Result<()> {
        let prefix = memory_prefix();
        let key = "shards/part-00000.w.parquet";
        let good = b"the shard's bytes".to_vec();
        prefix.put(key, good.clone(), WriteMode::Overwrite)?;
        let etag = prefix.head(key)?.and_then(|l| l.etag);
        let rec = record(&good, etag.as_deref());
        assert_eq!(check_object(&prefix, 0, &rec)?, None);
        assert!(matches!(hash_object(&prefix, 0, &rec)?, Hashed::Good { etag: e } if e == etag));
        let mut flipped = good.clone();
        flipped[3] ^= 1;
        prefix.put(key, flipped, WriteMode::Overwrite)?;
        let why = check_object(&prefix, 0, &rec)?.unwrap_or_default();
        assert!(why.contains("replaced"), "{why}");
        let Hashed::Damaged(why) = hash_object(&prefix, 0, &rec)? else {
            panic!("a flipped byte hashes differently")
        };
        assert!(why.contains("sha256"), "{why}");
        // A record of an older version (no ETag) is checked by size only, but hashed fully.
        let old = record(&good, None);
        assert_eq!(check_object(&prefix, 0, &old)?, None);
        assert!(matches!(hash_object(&prefix, 0, &old)?, Hashed::Damaged(_)));
        prefix.put(key, b"short".to_vec(), WriteMode::Overwrite)?;
        let why = check_object(&prefix, 0, &old)?.unwrap_or_default();
        assert!(why.contains("has 5 bytes"), "{why}");
        prefix.delete(key)?;
        let why = check_object(&prefix, 0, &rec)?.unwrap_or_default();
        assert!(why.contains("missing"), "{why}");
        assert!(
            matches!(hash_object(&prefix, 0, &rec)?, Hashed::Damaged(w) if w.contains("missing"))
        );
        Ok(())
    }
}
