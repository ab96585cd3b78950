//! `verify` of one shard of a job in a bucket: the object its record names read from the
//! bucket and hashed (never a local copy), then, with `repair` and under the shard's lease, a
//! damaged shard moved aside ([`crate::quarantine`]) or a good object's new ETag recorded, as
//! `verify` on disk moves a damaged shard or re-records a stamp.

use crate::commit::read_record_version;
use crate::integrity::{hash_object, Hashed};
use crate::keys;
use crate::lease::{acquire, Acquired};
use anyhow::{bail, Context, Result};
use sparc3d_schema::CompletionRecord;
use sparc3d_sources::objects::{Prefix, Version, WriteMode, Written};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// The lease `verify` holds while it changes a shard (seconds; renewed by its heartbeat).
const LEASE_TTL_S: f64 = 60.0;

/// What [`verify_shard`] found.
#[derive(Debug, Clone, PartialEq)]
pub enum Verified {
    /// No record: nothing to verify.
    NotFinished,
    /// The object's bytes are the recorded ones; `rerecorded` when its ETag was not the
    /// recorded one (a record of an older version, or the same bytes uploaded again) and the
    /// new one was recorded, so that the cheap checks of `status` and `run` trust it.
    Good {
        /// The record read.
        record: Box<CompletionRecord>,
        /// Whether the ETag was recorded.
        rerecorded: bool,
    },
    /// Damaged; moved aside to the quarantine folder `moved_to` (`None` when only reported).
    Damaged {
        /// What is wrong.
        reason: String,
        /// The URL of the quarantine folder.
        moved_to: Option<String>,
    },
    /// Needed a change but was left alone: a live worker holds its lease, or the shard
    /// changed while it was read.
    Busy {
        /// What was found, and why it was left alone.
        reason: String,
    },
}

/// Hashes shard `shard`'s object in the bucket against its record; with `repair`, changes
/// the shard as [`Verified`] says. A record of another fingerprint is an error (a mixed job
/// is never repaired by itself).
pub fn verify_shard(
    prefix: &Prefix<'static>,
    shard: u64,
    fingerprint: &str,
    repair: bool,
) -> Result<Verified> {
    let Some((record, version)) = read_record_version(prefix, shard)? else {
        return Ok(Verified::NotFinished);
    };
    if record.fingerprint != fingerprint {
        bail!(
            "{}: a record of another config (fingerprint {}, the job's is {fingerprint}); \
             configs are never mixed",
            prefix.url(&keys::record(shard)),
            record.fingerprint
        );
    }
    let found = match record.shard == shard {
        true => hash_object(prefix, shard, &record)?,
        false => Hashed::Damaged(format!("its record is shard {}'s", record.shard)),
    };
    let change = match &found {
        Hashed::Damaged(_) => true,
        Hashed::Good { etag } => etag.is_some() && *etag != record.object_etag,
    };
    match (found, change && repair) {
        (Hashed::Damaged(reason), false) => Ok(Verified::Damaged {
            reason,
            moved_to: None,
        }),
        (Hashed::Good { .. }, false) => Ok(good(record)),
        (found, true) => {
            let seen = Seen {
                shard,
                record,
                version,
                found,
            };
            under_lease(prefix, &seen)
        }
    }
}

fn good(record: CompletionRecord) -> Verified {
    Verified::Good {
        record: Box::new(record),
        rerecorded: false,
    }
}

/// What a shard was found to be, to be acted on under its lease.
struct Seen {
    shard: u64,
    record: CompletionRecord,
    /// The version of the record object read.
    version: Version,
    found: Hashed,
}

/// Takes the shard's lease and, if neither the record nor the object changed since they were
/// read, moves the shard aside or records the object's ETag.
fn under_lease(prefix: &Prefix<'static>, seen: &Seen) -> Result<Verified> {
    let reason = match &seen.found {
        Hashed::Damaged(why) => why.clone(),
        Hashed::Good { .. } => "its object's ETag is not the recorded one".to_string(),
    };
    let owner = sparc3d_workers::lease::owner_name();
    let stop = Arc::new(AtomicBool::new(false));
    let lease = match acquire(prefix, seen.shard, &owner, LEASE_TTL_S, stop)? {
        Acquired::Held(l) => l,
        Acquired::Busy(h) => {
            let reason = format!("{reason}; leased by {}, left alone", h.owner);
            return Ok(Verified::Busy { reason });
        }
        Acquired::Contended => {
            let reason = format!("{reason}; several workers taking its lease, left alone");
            return Ok(Verified::Busy { reason });
        }
    };
    let result = act(prefix, seen, reason);
    lease.release();
    result
}

/// The change [`under_lease`] makes, the lease held.
fn act(prefix: &Prefix<'_>, seen: &Seen, reason: String) -> Result<Verified> {
    let shard = seen.shard;
    if let Some(why) = changed_since(prefix, seen)? {
        let reason = format!("{reason}; {why} while verify read it, left alone (verify again)");
        return Ok(Verified::Busy { reason });
    }
    let Hashed::Good { etag } = &seen.found else {
        let moved_to = crate::quarantine::quarantine(prefix, shard, &reason)?;
        return Ok(Verified::Damaged { reason, moved_to });
    };
    let record = CompletionRecord {
        object_etag: etag.clone(),
        ..seen.record.clone()
    };
    let bytes = serde_json::to_vec_pretty(&record)?;
    let key = keys::record(shard);
    let replace = WriteMode::Replace(seen.version.clone());
    match prefix
        .put(&key, bytes, replace)
        .with_context(|| format!("shard {shard}: recording its object's ETag"))?
    {
        Written::Done(_) => Ok(Verified::Good {
            record: Box::new(record),
            rerecorded: true,
        }),
        Written::Refused => Ok(Verified::Busy {
            reason: format!("{reason}; its record changed while verify read it, left alone"),
        }),
    }
}

/// Why the shard is not as it was read (its record or its object changed), if it changed.
fn changed_since(prefix: &Prefix<'_>, seen: &Seen) -> Result<Option<String>> {
    let now = read_record_version(prefix, seen.shard)?;
    if now.as_ref().map(|(r, _)| r) != Some(&seen.record) {
        return Ok(Some("its record changed".into()));
    }
    let Hashed::Good { etag } = &seen.found else {
        return Ok(None);
    };
    let name = keys::object_name(seen.shard, &seen.record);
    let key = keys::data(&name);
    let found = prefix
        .head(&key)
        .with_context(|| format!("shard {}: looking up {}", seen.shard, prefix.url(&key)))?;
    Ok((found.and_then(|l| l.etag) != *etag).then(|| "its object changed".to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commit::read_record;
    use crate::lease::tests::memory_prefix;

    /// A record of an older version (no ETag) over a good object: `--dry-run` reports it good
    /// and changes nothing, `verify` records the ETag once; then the object's bytes change:
    /// damaged, moved aside with the object, and the shard is unfinished.
    #[test]
    fn an_unrecorded_etag_is_recorded_and_a_changed_object_moved_aside() -> Result<()> {
        let prefix = memory_prefix();
        let data = b"the shard's bytes".to_vec();
        let object = "shards/part-00000.w.parquet";
        prefix.put(object, data.clone(), WriteMode::Overwrite)?;
        let record = crate::integrity::tests::record(&data, None);
        let bytes = serde_json::to_vec(&record)?;
        prefix.put(&keys::record(0), bytes, WriteMode::Overwrite)?;
        let rerecorded = |v: &Verified| matches!(v, Verified::Good { rerecorded: r, .. } if *r);
        assert!(!rerecorded(&verify_shard(&prefix, 0, "fp", false)?));
        assert!(rerecorded(&verify_shard(&prefix, 0, "fp", true)?));
        let etag = prefix.head(object)?.and_then(|l| l.etag);
        assert_eq!(read_record(&prefix, 0)?.and_then(|r| r.object_etag), etag);
        assert!(!rerecorded(&verify_shard(&prefix, 0, "fp", true)?));
        assert!(
            verify_shard(&prefix, 0, "other", true).is_err(),
            "a mixed job"
        );
        let mut flipped = data;
        flipped[0] ^= 1;
        prefix.put(object, flipped, WriteMode::Overwrite)?;
        let Verified::Damaged { moved_to, .. } = verify_shard(&prefix, 0, "fp", true)? else {
            panic!("a changed object is damage")
        };
        assert!(moved_to.is_some());
        assert_eq!(read_record(&prefix, 0)?, None);
        assert_eq!(prefix.head(object)?, None);
        let kept = prefix.list("quarantine/")?;
        assert_eq!(kept.len(), 3, "record, object and reason kept: {kept:?}");
        assert_eq!(verify_shard(&prefix, 0, "fp", true)?, Verified::NotFinished);
        Ok(())
    }
}
