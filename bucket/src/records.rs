//! The completion records of a bucket job's finished shards, as the read-only commands read
//! them: only the records a listing shows, each read once per version. A record read is kept
//! in the local copy under the ETag the store gave it (`.records/part-NNNNN.<etag>.json`) and
//! used again while the listing shows that ETag, so a later `status` reads only the records
//! new since; the reads go [`crate::parallel::IN_FLIGHT`] at a time. A store that gives no
//! ETag gets no cache.

use crate::commit::read_record_version;
use crate::listing::JobListing;
use anyhow::{Context, Result};
use sparc3d_schema::{CompletionRecord, JobLayout};
use sparc3d_sources::objects::Prefix;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The folder of the local copy `root` that keeps the records read.
fn cache_dir(root: &Path) -> PathBuf {
    root.join(".records")
}

/// The cache file of `shard`'s record of ETag `etag`; none for an ETag that is not a plain
/// token (it names a file).
fn cache_file(root: &Path, shard: u64, etag: &str) -> Option<PathBuf> {
    let plain = !etag.is_empty()
        && etag.len() <= 128
        && etag.chars().all(|c| c.is_ascii_alphanumeric() || c == '-');
    plain.then(|| cache_dir(root).join(format!("{}.{etag}.json", JobLayout::shard_name(shard))))
}

/// Every record the listing shows, by shard: from the cache in `root` where the listed ETag
/// is the one read before, else read from the bucket (a record deleted since the listing is
/// left out). Cache files of records no longer listed go.
pub fn read(
    prefix: &Prefix<'_>,
    root: &Path,
    listing: &JobListing,
) -> Result<BTreeMap<u64, CompletionRecord>> {
    let dir = cache_dir(root);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut found = BTreeMap::new();
    let mut wanted = Vec::new();
    for (&shard, listed) in listing.records() {
        match listed.etag.as_deref().and_then(|e| cached(root, shard, e)) {
            Some(record) => {
                found.insert(shard, record);
            }
            None => wanted.push(shard),
        }
    }
    let read = crate::parallel::each(&wanted, crate::parallel::IN_FLIGHT, |&shard| {
        fetch(prefix, root, shard)
    })?;
    found.extend(
        wanted
            .into_iter()
            .zip(read)
            .filter_map(|(s, r)| Some((s, r?))),
    );
    forget_unlisted(&dir, listing)?;
    Ok(found)
}

/// The record of `shard` kept under `etag`, if it is there and reads.
fn cached(root: &Path, shard: u64, etag: &str) -> Option<CompletionRecord> {
    let bytes = std::fs::read(cache_file(root, shard, etag)?).ok()?;
    serde_json::from_slice(&bytes).ok()
}

/// Reads `shard`'s record from the bucket and keeps it under the ETag it was read with.
fn fetch(prefix: &Prefix<'_>, root: &Path, shard: u64) -> Result<Option<CompletionRecord>> {
    let Some((record, version)) = read_record_version(prefix, shard)? else {
        return Ok(None);
    };
    let etag = version
        .etag
        .as_deref()
        .map(sparc3d_sources::objects::bare_etag);
    if let Some(file) = etag.and_then(|e| cache_file(root, shard, &e)) {
        let bytes = serde_json::to_vec(&record)?;
        sparc3d_workers::fsutil::write_atomic(&file, &bytes, "keeping a completion record")?;
    }
    Ok(Some(record))
}

/// Removes the cache files that are not of a record the listing shows with that ETag.
fn forget_unlisted(dir: &Path, listing: &JobListing) -> Result<()> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("listing {}", dir.display()))?;
    for entry in entries {
        let entry = entry.with_context(|| format!("listing {}", dir.display()))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let listed = crate::keys::shard_of(&name).and_then(|s| listing.records().get(&s));
        let current = listed
            .and_then(|l| l.etag.as_deref())
            .is_some_and(|etag| name.ends_with(&format!(".{etag}.json")));
        if !current {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    Ok(())
}
