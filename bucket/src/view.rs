//! What the read-only commands see of a job whose home is a bucket.
//!
//! - [`shard_states`]: each shard's state from one listing of `shards/` and the leases: done
//!   (a record whose object is there with the recorded size), running (a live lease), pending,
//!   or damaged (a record whose object is missing or of another size); the checkpoints of the
//!   unfinished shards are brought into the local copy, so that `status` counts their items.
//! - [`mirror`]: a job folder made of the bucket's finished shards, each downloaded once (kept
//!   while its record is unchanged) and hashed on the way, for `ls`, `failures`, `inspect`,
//!   `show`, `export`, `report` and `verify`. A download that does not match its record keeps
//!   the record's size and sha256, so those commands report the shard as damaged, as they
//!   would on disk.

use crate::commit::read_record;
use crate::keys;
use anyhow::{Context, Result};
use sparc3d_schema::CompletionRecord;
use sparc3d_sources::objects::Prefix;
use sparc3d_workers::store::state::ShardState;
use sparc3d_workers::Job;
use std::collections::BTreeMap;

/// The objects under `shards/`, by name, with their sizes.
fn shard_objects(prefix: &Prefix<'_>) -> Result<BTreeMap<String, u64>> {
    let found = prefix
        .list(keys::SHARDS)
        .with_context(|| format!("listing {}", prefix.url(keys::SHARDS)))?;
    Ok(found
        .into_iter()
        .map(|l| {
            let key = prefix.relative_key(&l);
            (key.trim_start_matches(keys::SHARDS).to_string(), l.size)
        })
        .collect())
}

/// The name of the object a record's shard is in.
pub fn object_name(shard: u64, record: &CompletionRecord) -> String {
    record
        .object
        .clone()
        .unwrap_or_else(|| format!("{}.parquet", sparc3d_schema::JobLayout::shard_name(shard)))
}

/// Every shard's state, and the checkpoints of the unfinished ones brought into `job`'s
/// folder (the local copy made by [`crate::scratch::pull_job`]).
pub fn shard_states(prefix: &Prefix<'_>, job: &Job) -> Result<Vec<ShardState>> {
    let objects = shard_objects(prefix)?;
    let mut states = Vec::new();
    for shard in 0..job.file.shards {
        let state = match objects.contains_key(&keys::record(shard)[keys::SHARDS.len()..]) {
            true => finished_state(prefix, shard, &objects)?,
            false => unfinished_state(prefix, job, shard)?,
        };
        states.push(state);
    }
    Ok(states)
}

fn finished_state(
    prefix: &Prefix<'_>,
    shard: u64,
    objects: &BTreeMap<String, u64>,
) -> Result<ShardState> {
    let Some(record) = read_record(prefix, shard)? else {
        return Ok(ShardState::Pending);
    };
    let name = object_name(shard, &record);
    Ok(match objects.get(&name) {
        Some(&size) if size == record.bytes => ShardState::Done(record),
        Some(&size) => ShardState::Damaged(format!(
            "its object {name} has {size} bytes, its record says {}",
            record.bytes
        )),
        None => ShardState::Damaged(format!("its object {name} is missing")),
    })
}

fn unfinished_state(prefix: &Prefix<'_>, job: &Job, shard: u64) -> Result<ShardState> {
    crate::work::pull_checkpoints(prefix, job, shard)?;
    let now = sparc3d_workers::now();
    Ok(match crate::lease::read(prefix, shard)? {
        Some(lease) if now <= lease.expires_at => ShardState::Running(lease),
        _ => ShardState::Pending,
    })
}

/// The most bytes [`mirror`] downloads in one call unless `SPARC3D_VIEW_MAX_BYTES` says
/// otherwise: a read-only command on a large job would otherwise copy the whole dataset.
pub const DEFAULT_MAX_BYTES: u64 = 20 << 30;

/// Makes `job`'s folder (a local copy of the bucket job's files) hold every finished shard of
/// the bucket as a job folder does: `shards/part-NNNNN.parquet` and its record. Shards already
/// there under an unchanged record are kept. Returns how many were downloaded. More than
/// `SPARC3D_VIEW_MAX_BYTES` (default [`DEFAULT_MAX_BYTES`]) to download is refused before
/// anything is, naming the size.
pub fn mirror(prefix: &Prefix<'_>, job: &Job) -> Result<u64> {
    let layout = &job.layout;
    std::fs::create_dir_all(layout.shards_dir())
        .with_context(|| format!("creating {}", layout.shards_dir().display()))?;
    let mut todo = Vec::new();
    for shard in 0..job.file.shards {
        let Some(record) = read_record(prefix, shard)? else {
            let _ = std::fs::remove_file(layout.completion(shard));
            let _ = std::fs::remove_file(layout.shard_file(shard));
            continue;
        };
        let local = CompletionRecord {
            object: None,
            ..record.clone()
        };
        if !kept(job, shard, &local) {
            todo.push((shard, record, local));
        }
    }
    check_size(prefix, &todo)?;
    let fetched = todo.len() as u64;
    for (shard, record, local) in todo {
        let _ = std::fs::remove_file(layout.completion(shard));
        let name = object_name(shard, &record);
        let file = layout.shard_file(shard);
        let got = prefix
            .download(&keys::data(&name), &file)
            .with_context(|| format!("downloading shard {shard}"))?;
        // A stamp only when the bytes are the recorded ones: otherwise every check hashes the
        // file and finds it damaged.
        let stamp = (got.sha256 == record.sha256 && got.bytes == record.bytes)
            .then(|| std::fs::metadata(&file).ok())
            .flatten()
            .map(|m| sparc3d_workers::fsutil::file_stamp(&m));
        let local = CompletionRecord { stamp, ..local };
        let bytes = serde_json::to_vec_pretty(&local)?;
        crate::scratch::replace(&layout.completion(shard), &bytes)?;
    }
    Ok(fetched)
}

/// Refuses a download of more than the view's byte budget.
fn check_size(
    prefix: &Prefix<'_>,
    todo: &[(u64, CompletionRecord, CompletionRecord)],
) -> Result<()> {
    let bytes: u64 = todo.iter().map(|(_, r, _)| r.bytes).sum();
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
/// stamp) and its file is there with the recorded size.
fn kept(job: &Job, shard: u64, record: &CompletionRecord) -> bool {
    let layout = &job.layout;
    let Ok(bytes) = std::fs::read(layout.completion(shard)) else {
        return false;
    };
    let Ok(have) = serde_json::from_slice::<CompletionRecord>(&bytes) else {
        return false;
    };
    let same = CompletionRecord {
        stamp: None,
        ..have.clone()
    } == CompletionRecord {
        stamp: None,
        ..record.clone()
    };
    let size = std::fs::metadata(layout.shard_file(shard)).map(|m| m.len());
    same && size.is_ok_and(|s| s == record.bytes)
}
