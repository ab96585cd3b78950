//! A manifest's rows frozen into a job's items (`sparc3d init`): every row's sha256 well formed, every
//! id known (a row with neither id nor sha256 is identified by its file's sha256, hashed here),
//! ids unique, and each item's shard. Problems are named by row, the first few in full and the
//! rest counted.

use crate::record::{FrozenItem, ManifestRecord};
use crate::table::RawRecord;
use anyhow::{bail, Result};
use rayon::prelude::*;
use std::collections::HashMap;

/// Rows listed in full when many have a problem; the rest are counted.
const LISTED: usize = 10;

/// The rows' items in order, each with its index and shard (`index / shard_size`). Says how
/// many items have no sha256 to check their file against before it is converted.
pub fn freeze(records: Vec<RawRecord>, shard_size: u32) -> Result<Vec<FrozenItem>> {
    check_sha256s(&records)?;
    let items = assign(identify(records)?, shard_size)?;
    let unchecked = items.iter().filter(|i| i.record.sha256.is_none()).count();
    if unchecked > 0 {
        eprintln!(
            "note: {unchecked} items have an id but no sha256: their rows record the sha256 of \
             the bytes converted, but a file changed after init cannot be told from the one \
             meant (a sha256 column, as `sparc3d manifest build` writes, has each file checked \
             before it is converted)"
        );
    }
    Ok(items)
}

/// Whether `sha` is a sha256 as hex (64 digits, either case).
fn is_sha256(sha: &str) -> bool {
    sha.len() == 64 && sha.bytes().all(|b| b.is_ascii_hexdigit())
}

/// Refuses rows whose sha256 is not one: a file's bytes are checked against it.
fn check_sha256s(records: &[RawRecord]) -> Result<()> {
    let bad: Vec<String> = records
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let sha = r.sha256.as_deref()?;
            (!is_sha256(sha)).then(|| format!("row {}: {sha:?}", i + 1))
        })
        .collect();
    if !bad.is_empty() {
        bail!(
            "{} rows have a sha256 that is not 64 hex digits (a file's bytes are checked against \
             it before they are converted): {}",
            bad.len(),
            listing(&bad)
        );
    }
    Ok(())
}

/// A row's id and frozen sha256: the manifest's own, or (a row with neither) the sha256 of the
/// file, which is then also the id.
fn id_and_sha(r: &RawRecord) -> Result<(String, Option<String>)> {
    Ok(match (&r.id, &r.sha256) {
        (Some(id), sha) => (id.clone(), sha.clone()),
        (None, Some(sha)) => (sha.clone(), Some(sha.clone())),
        (None, None) => {
            let sha = crate::hash::file_sha256(std::path::Path::new(&r.uri))?;
            (sha.clone(), Some(sha))
        }
    })
}

/// Every row with its id (files hashed in parallel); refused naming every file that could not
/// be hashed.
fn identify(records: Vec<RawRecord>) -> Result<Vec<ManifestRecord>> {
    let total = records.len();
    let results: Vec<Result<ManifestRecord, String>> = records
        .into_par_iter()
        .enumerate()
        .map(|(i, r)| {
            let (id, sha256) = id_and_sha(&r).map_err(|e| format!("row {}: {e}", i + 1))?;
            Ok(ManifestRecord {
                id,
                uri: r.uri,
                sha256,
                format: r.format,
                extra: r.extra,
            })
        })
        .collect();
    let unreadable: Vec<String> = results.iter().filter_map(|r| r.clone().err()).collect();
    if !unreadable.is_empty() {
        bail!(
            "{} of {total} files could not be hashed for their ids (a row without id or sha256 \
             is identified by its file's sha256): {}",
            unreadable.len(),
            listing(&unreadable)
        );
    }
    Ok(results.into_iter().flatten().collect())
}

/// The records as items with their index and shard; duplicate ids are refused.
fn assign(records: Vec<ManifestRecord>, shard_size: u32) -> Result<Vec<FrozenItem>> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut items = Vec::with_capacity(records.len());
    let mut dups = Vec::new();
    for (i, rec) in records.into_iter().enumerate() {
        if let Some(first) = seen.get(&rec.id) {
            dups.push(format!("{} (rows {} and {})", rec.id, first + 1, i + 1));
            continue;
        }
        seen.insert(rec.id.clone(), i);
        let index = items.len() as u64;
        items.push(FrozenItem {
            index,
            shard: index / shard_size.max(1) as u64,
            record: rec,
        });
    }
    if !dups.is_empty() {
        bail!(
            "the manifest has {} duplicate ids, e.g. {}; ids must be unique",
            dups.len(),
            dups.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
        );
    }
    Ok(items)
}

/// The first [`LISTED`] lines of `bad` in full and the rest counted.
fn listing(bad: &[String]) -> String {
    let mut text = bad
        .iter()
        .take(LISTED)
        .cloned()
        .collect::<Vec<_>>()
        .join("; ");
    if bad.len() > LISTED {
        text.push_str(&format!("; and {} more", bad.len() - LISTED));
    }
    text
}
