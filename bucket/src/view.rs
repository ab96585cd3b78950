//! What the read-only commands see of a job whose home is a bucket.
//!
//! - [`shard_states`]: each shard's state from one listing of the job ([`JobListing`]) and
//!   the records, leases and checkpoints it shows: done (a record whose object is there as
//!   recorded: its size, and its ETag when the record has one), running (a live lease),
//!   pending, or damaged (a record whose object is missing, of another size or replaced:
//!   [`crate::integrity::object_mismatch`]); the checkpoints of the unfinished shards are
//!   brought into the local copy, so that `status` counts their items. A shard with nothing in
//!   the bucket costs no request.
//! - [`mirror`]: a job folder made of the bucket's finished shards, for `ls`, `failures`,
//!   `inspect`, `show`, `export`, `report`, `validate`, `eval` and `retry`, each downloaded
//!   once and hashed on the way, and kept only while the listing shows the object it was
//!   copied from (same ETag and size). A download that does not match its record keeps the
//!   record's size and sha256, and a missing object leaves the record without its file, so
//!   those commands report the shard as damaged, as they would on disk. (`verify` reads the
//!   bucket itself: [`crate::verify`].)

use crate::integrity::object_mismatch;
use crate::keys::{self, object_name};
use crate::listing::JobListing;
use crate::parallel::{self, IN_FLIGHT};
use anyhow::{Context, Result};
use sparc3d_schema::CompletionRecord;
use sparc3d_sources::list::Listed;
use sparc3d_sources::objects::Prefix;
use sparc3d_sources::FetchErrorKind;
use sparc3d_workers::store::state::ShardState;
use sparc3d_workers::Job;
use std::collections::BTreeMap;

/// Every shard's state, and the checkpoints of the unfinished ones brought into `job`'s
/// folder (the local copy made by [`crate::scratch::pull_job`]). One listing of the job
/// ([`JobListing`]), then reads of only what it shows: the records not read before
/// ([`crate::records`]), the leases and the new checkpoints of unfinished shards, each
/// [`IN_FLIGHT`] at a time.
pub fn shard_states(prefix: &Prefix<'_>, job: &Job) -> Result<Vec<ShardState>> {
    let listing = JobListing::read(prefix)?;
    let records = crate::records::read(prefix, &job.layout.root, &listing)?;
    let unfinished = |shard: &u64| !records.contains_key(shard);
    crate::checkpoint::sync_checkpoints(prefix, job, &listing, &unfinished)?;
    let leased: Vec<u64> = listing
        .leased_shards()
        .filter(|s| *s < job.file.shards && unfinished(s))
        .collect();
    let leases = parallel::each(&leased, IN_FLIGHT, |&s| crate::lease::read(prefix, s))?;
    let mut leases: BTreeMap<u64, _> = leased.into_iter().zip(leases).collect();
    let now = sparc3d_workers::clock::now();
    let objects = listing.shard_objects();
    Ok((0..job.file.shards)
        .map(|shard| match records.get(&shard) {
            Some(record) => finished_state(shard, record, objects),
            None => match leases.remove(&shard).flatten() {
                Some(lease) if now <= lease.expires_at => ShardState::Running(lease),
                _ => ShardState::Pending,
            },
        })
        .collect())
}

fn finished_state(
    shard: u64,
    record: &CompletionRecord,
    objects: &BTreeMap<String, Listed>,
) -> ShardState {
    let found = objects.get(&object_name(shard, record));
    match object_mismatch(shard, record, found) {
        None => ShardState::Done(record.clone()),
        Some(why) => ShardState::Damaged(why),
    }
}

/// The most bytes [`mirror`] downloads in one call unless `SPARC3D_VIEW_MAX_BYTES` says
/// otherwise: a read-only command on a large job would otherwise copy the whole dataset.
pub const DEFAULT_MAX_BYTES: u64 = 20 << 30;

/// What [`mirror`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mirrored {
    /// Shards downloaded now.
    pub fetched: u64,
    /// Finished shards whose object the listing shows is not the one their record names
    /// (missing, of another size, replaced), with why; the commands reading the copy report a
    /// missing or changed one as damaged.
    pub damaged: Vec<(u64, String)>,
}

/// Makes `job`'s folder (a local copy of the bucket job's files) hold every finished shard of
/// the bucket as a job folder does: `shards/part-NNNNN.parquet` and its record. A local copy
/// is kept only while its record is unchanged and the listing shows the object it was copied
/// from (its ETag, recorded in the local record's `object_etag`, and its size); any other is
/// downloaded again. A shard whose object is missing keeps its record without the file, so
/// that it reads as damaged. More than `SPARC3D_VIEW_MAX_BYTES` (default
/// [`DEFAULT_MAX_BYTES`]) to download is refused before anything is, naming the size.
pub fn mirror(prefix: &Prefix<'_>, job: &Job) -> Result<Mirrored> {
    let layout = &job.layout;
    std::fs::create_dir_all(layout.shards_dir())
        .with_context(|| format!("creating {}", layout.shards_dir().display()))?;
    let listing = JobListing::read(prefix)?;
    let records = crate::records::read(prefix, &layout.root, &listing)?;
    let objects = listing.shard_objects();
    let mut todo = Vec::new();
    let mut damaged = Vec::new();
    for shard in 0..job.file.shards {
        let Some(record) = records.get(&shard) else {
            forget_local(job, shard);
            continue;
        };
        let listed = objects.get(&object_name(shard, record));
        if let Some(why) = object_mismatch(shard, record, listed) {
            damaged.push((shard, why));
        }
        match listed {
            None => without_object(job, shard, record)?,
            Some(l) if kept(job, shard, record, l) => {}
            Some(_) => todo.push((shard, record.clone())),
        }
    }
    check_size(prefix, &todo)?;
    let fetched = todo.len() as u64;
    let got = parallel::each(&todo, IN_FLIGHT, |(shard, record)| {
        fetch(prefix, job, *shard, record)
    })?;
    for ((shard, record), there) in todo.iter().zip(got) {
        if !there {
            let name = object_name(*shard, record);
            damaged.push((
                *shard,
                format!("its object shards/{name} is missing from the bucket"),
            ));
        }
    }
    damaged.sort();
    Ok(Mirrored { fetched, damaged })
}

/// Removes the local copy's record and file of `shard`, which the bucket has not finished.
fn forget_local(job: &Job, shard: u64) {
    let layout = &job.layout;
    for path in [layout.completion(shard), layout.shard_file(shard)] {
        if path.exists() {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// The bucket's `record` as the local copy holds it: no object name (the file is
/// `part-NNNNN.parquet`), the local file's `stamp` and the ETag of the object copied.
fn local_record(
    record: &CompletionRecord,
    stamp: Option<sparc3d_schema::FileStamp>,
    object_etag: Option<String>,
) -> CompletionRecord {
    CompletionRecord {
        object: None,
        stamp,
        object_etag,
        ..record.clone()
    }
}

/// A finished shard whose object is missing from the bucket: its record without the file, as
/// a job folder that lost a shard file has it.
fn without_object(job: &Job, shard: u64, record: &CompletionRecord) -> Result<()> {
    let file = job.layout.shard_file(shard);
    match std::fs::remove_file(&file) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            return Err(e).with_context(|| format!("removing {}", file.display()))
        }
        _ => {}
    }
    let bytes = serde_json::to_vec_pretty(&local_record(record, None, None))?;
    crate::scratch::replace(&job.layout.completion(shard), &bytes)
}

/// Downloads `shard`'s object into the local copy, hashing it on the way, and writes its
/// local record; `false` when the object was gone by then.
fn fetch(prefix: &Prefix<'_>, job: &Job, shard: u64, record: &CompletionRecord) -> Result<bool> {
    let layout = &job.layout;
    let _ = std::fs::remove_file(layout.completion(shard));
    let key = keys::data(&object_name(shard, record));
    let file = layout.shard_file(shard);
    let got = match prefix.download(&key, &file) {
        Ok(got) => got,
        Err(e) if e.kind == FetchErrorKind::NotFound => {
            without_object(job, shard, record)?;
            return Ok(false);
        }
        Err(e) => {
            return Err(e).with_context(|| format!("downloading shard {shard} ({key})"));
        }
    };
    // A stamp only when the bytes are the recorded ones: otherwise every check hashes the
    // file and finds it damaged.
    let stamp = (got.sha256 == record.sha256 && got.bytes == record.bytes)
        .then(|| std::fs::metadata(&file).ok())
        .flatten()
        .map(|m| sparc3d_workers::fsutil::file_stamp(&m));
    let bytes = serde_json::to_vec_pretty(&local_record(record, stamp, got.etag))?;
    crate::scratch::replace(&layout.completion(shard), &bytes)?;
    Ok(true)
}

/// Refuses a download of more than the view's byte budget.
fn check_size(prefix: &Prefix<'_>, todo: &[(u64, CompletionRecord)]) -> Result<()> {
    let bytes: u64 = todo.iter().map(|(_, r)| r.bytes).sum();
    let max = match std::env::var("SPARC3D_VIEW_MAX_BYTES") {
        Ok(v) => v
            .trim()
            .parse::<u64>()
            .with_context(|| format!("SPARC3D_VIEW_MAX_BYTES={v:?} is not a byte count"))?,
        Err(_) => DEFAULT_MAX_BYTES,
    };
    if bytes > max {
        anyhow::bail!(
            "{}: this command reads a local copy of the finished shards, and {} shards of {:.1} \
             GB are not copied yet, over the {:.1} GB allowed (SPARC3D_VIEW_MAX_BYTES); `sparc3d \
             status` reads only records, the Python reader reads the bucket itself",
            prefix.root(),
            todo.len(),
            bytes as f64 / 1e9,
            max as f64 / 1e9
        );
    }
    Ok(())
}

/// Whether the local copy of `shard` is the bucket's: its record is `record` (but for the
/// stamp and the ETag), its file is there with the recorded size, and it was copied from the
/// object `listed` (the same ETag; a store that lists no ETag gets no trust).
fn kept(job: &Job, shard: u64, record: &CompletionRecord, listed: &Listed) -> bool {
    let layout = &job.layout;
    let Ok(bytes) = std::fs::read(layout.completion(shard)) else {
        return false;
    };
    let Ok(have) = serde_json::from_slice::<CompletionRecord>(&bytes) else {
        return false;
    };
    let copied_from = have.object_etag.clone();
    let same = local_record(&have, None, None) == local_record(record, None, None);
    let size = std::fs::metadata(layout.shard_file(shard)).map(|m| m.len());
    same && copied_from.is_some()
        && copied_from == listed.etag
        && size.is_ok_and(|s| s == record.bytes)
}
