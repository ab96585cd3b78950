//! A manifest's rows frozen into a job's items (`sparc3d init`): every row's sha256 well formed, every
//! id known (a row with neither id nor sha256 is identified by its file's sha256, hashed here),
//! ids unique, and each item's shard. Problems are named by row, the first few in full and the
//! rest counted. [`append`] freezes the rows a growing job does not have yet (`sparc3d add`)
//! into new shards after its last one.

use crate::record::{FrozenItem, ManifestRecord};
use crate::table::RawRecord;
use anyhow::{bail, Result};
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap, HashSet};

/// Rows listed in full when many have a problem; the rest are counted.
const LISTED: usize = 10;

/// The rows' items in order, each with its index and shard (`index / shard_size`). Says how
/// many items have no sha256 to check their file against before it is converted.
pub fn freeze(records: Vec<RawRecord>, shard_size: u32) -> Result<Vec<FrozenItem>> {
    check_sha256s(&records)?;
    let items = assign(identify(records)?, shard_size, (0, 0))?;
    note_unchecked(&items);
    Ok(items)
}

/// The rows of a growing job's new manifest (or folder) that it does not have yet.
#[derive(Debug)]
pub struct Appended {
    /// The new items, indexed after the job's last item, in new shards after its last shard.
    pub items: Vec<FrozenItem>,
    /// Rows whose id the job has already (left out).
    pub already: usize,
}

/// Freezes the rows whose id is not among `existing` (a job's items, in order) as items after
/// them: indices from `existing.len()`, shards from the one after the last existing item's, so
/// the job's finished shards are never touched. Every new item gets the job's provenance
/// columns too (`""` where its row has none), so the new shards have at least the columns of
/// the earlier ones.
pub fn append(
    existing: &[FrozenItem],
    records: Vec<RawRecord>,
    shard_size: u32,
) -> Result<Appended> {
    check_sha256s(&records)?;
    let known: HashSet<&str> = existing.iter().map(|i| i.record.id.as_str()).collect();
    let columns: BTreeSet<&String> = existing
        .iter()
        .flat_map(|i| i.record.extra.keys())
        .collect();
    let total = records.len();
    let mut fresh: Vec<ManifestRecord> = identify(records)?
        .into_iter()
        .filter(|r| !known.contains(r.id.as_str()))
        .collect();
    for r in &mut fresh {
        for name in &columns {
            r.extra.entry((*name).clone()).or_default();
        }
    }
    let already = total - fresh.len();
    let start = (
        existing.len() as u64,
        existing.last().map_or(0, |i| i.shard + 1),
    );
    let items = assign(fresh, shard_size, start)?;
    note_unchecked(&items);
    Ok(Appended { items, already })
}

/// Says how many items have no sha256 to check their file against before it is converted.
fn note_unchecked(items: &[FrozenItem]) {
    let unchecked = items.iter().filter(|i| i.record.sha256.is_none()).count();
    if unchecked > 0 {
        eprintln!(
            "note: {unchecked} items have an id but no sha256: their rows record the sha256 of \
             the bytes converted, but a file changed after init cannot be told from the one \
             meant (a sha256 column, as `sparc3d manifest build` writes, has each file checked \
             before it is converted)"
        );
    }
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
            let sha = crate::hash::source_sha256(&r.uri)?;
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

/// The records as items with their index and shard, numbered from `start` (first index, first
/// shard): the k-th item gets index `start.0 + k` and shard `start.1 + k / shard_size`.
/// Duplicate ids are refused.
fn assign(
    records: Vec<ManifestRecord>,
    shard_size: u32,
    start: (u64, u64),
) -> Result<Vec<FrozenItem>> {
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut items = Vec::with_capacity(records.len());
    let mut dups = Vec::new();
    for (i, rec) in records.into_iter().enumerate() {
        if let Some(first) = seen.get(&rec.id) {
            dups.push(format!("{} (rows {} and {})", rec.id, first + 1, i + 1));
            continue;
        }
        seen.insert(rec.id.clone(), i);
        let k = items.len() as u64;
        items.push(FrozenItem {
            index: start.0 + k,
            shard: start.1 + k / u64::from(shard_size.max(1)),
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

#[cfg(test)]
mod tests {
    use super::*;

    fn row(id: &str, licence: Option<&str>) -> RawRecord {
        RawRecord {
            id: Some(id.into()),
            uri: format!("/d/{id}.obj"),
            sha256: None,
            format: None,
            extra: licence
                .map(|l| [("license".to_string(), l.to_string())].into())
                .unwrap_or_default(),
        }
    }

    #[test]
    fn appended_items_follow_in_new_shards_and_skip_known_ids() -> Result<()> {
        let first = freeze(
            vec![row("a", Some("cc0")), row("b", None), row("c", None)],
            2,
        )?;
        let shards: Vec<u64> = first.iter().map(|i| i.shard).collect();
        assert_eq!(shards, [0, 0, 1]);
        let more = vec![
            row("b", None),
            row("d", None),
            row("e", None),
            row("f", None),
        ];
        let added = append(&first, more, 2)?;
        assert_eq!(added.already, 1);
        let placed: Vec<(u64, u64)> = added.items.iter().map(|i| (i.index, i.shard)).collect();
        assert_eq!(
            placed,
            [(3, 2), (4, 2), (5, 3)],
            "after shard 1, never into it"
        );
        assert_eq!(
            added.items[0]
                .record
                .extra
                .get("license")
                .map(String::as_str),
            Some("")
        );
        assert!(append(&first, vec![row("x", None), row("x", None)], 2).is_err());
        assert!(append(&first, vec![row("a", None)], 2)?.items.is_empty());
        Ok(())
    }
}
