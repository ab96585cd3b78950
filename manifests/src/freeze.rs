//! A manifest's rows frozen into a job's items (`sparc3d init`): every row's sha256 well formed,
//! every id known (a row with neither id nor sha256 is identified by its file's sha256, hashed
//! here), ids unique. Problems are named by row, the first few in full and the rest counted.
//! [`Freezer`] does it a batch of rows at a time (a job's frozen manifest is written as it
//! goes, each item's shard given by the writer: `sparc3d_workers::frozen::write`); growing a
//! job (`sparc3d add`), it leaves out the rows whose id the job has.

use crate::problems::Problems;
use crate::record::ManifestRecord;
use crate::table::RawRecord;
use anyhow::{bail, Result};
use rayon::prelude::*;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::hash::{Hash, Hasher};

/// Rows listed in full when many have a problem; the rest are counted.
const LISTED: usize = 10;

/// The key an id is known by while freezing: 128 bits of two salted hashes of it (the
/// standard library's), so that ten million ids take 16 bytes each rather than their text (two
/// words, not a `u128`, whose 16-byte alignment would pad a map entry with its row to 32 bytes);
/// two different ids share a key with a chance of about 10⁻²² at 10⁸ ids. Keys live only in
/// the process that makes them, never in a file.
pub type IdKey = [u64; 2];

/// The [`IdKey`] of `id`.
pub fn id_key(id: &str) -> IdKey {
    let half = |salt: u8| {
        let mut h = std::collections::hash_map::DefaultHasher::new();
        salt.hash(&mut h);
        id.hash(&mut h);
        h.finish()
    };
    [half(0), half(1)]
}

/// Freezes a manifest's rows a batch at a time, in bounded memory but for the key of each id
/// seen ([`id_key`]): every row's sha256 well formed, every id known (a row with neither id nor
/// sha256 is identified by its file's sha256, hashed in parallel), ids unique (and, growing a
/// job, not the job's already). Problems are gathered as rows come and refused by
/// [`Freezer::finish`], the first few in full and the rest counted; once one is found no more
/// records are given out, since the freeze will be refused.
#[derive(Debug, Default)]
pub struct Freezer {
    /// The row each id was first seen in, by key.
    seen: HashMap<IdKey, u64>,
    /// The ids of the job being grown (rows with them are left out).
    known: HashSet<IdKey>,
    /// The growing job's provenance columns, given to every new item.
    columns: BTreeSet<String>,
    bad_sha: Problems,
    unreadable: Problems,
    duplicates: Problems,
    rows: u64,
    kept: u64,
    already: u64,
    unchecked: u64,
}

/// What a freeze did, once [`Freezer::finish`] found nothing wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frozen {
    /// Rows given.
    pub rows: u64,
    /// Items frozen (rows that were new).
    pub items: u64,
    /// Rows left out because the job has their id already.
    pub already: u64,
}

impl Freezer {
    /// A freezer of a new job's rows.
    pub fn new() -> Self {
        Self::default()
    }

    /// A freezer of the rows to add to a job with the ids `known` (their [`id_key`]s) and the
    /// provenance `columns`: rows with a known id are left out, and every new item gets every
    /// column (`""` where its row has none), so new shards have at least the earlier ones'.
    pub fn growing(known: HashSet<IdKey>, columns: BTreeSet<String>) -> Self {
        Self {
            known,
            columns,
            ..Self::default()
        }
    }

    /// Whether a problem was found: the freeze will be refused.
    pub fn failed(&self) -> bool {
        self.bad_sha.count() + self.unreadable.count() + self.duplicates.count() > 0
    }

    /// Freezes `rows` (each with its row number in the manifest): the records of the new
    /// items, in order. None once a problem has been found.
    pub fn batch(&mut self, rows: Vec<(u64, RawRecord)>) -> Vec<ManifestRecord> {
        self.rows += rows.len() as u64;
        for (n, r) in &rows {
            if let Some(sha) = r.sha256.as_deref().filter(|s| !is_sha256(s)) {
                self.bad_sha.add(|| format!("row {n}: {sha:?}"), LISTED);
            }
        }
        if self.bad_sha.count() > 0 {
            return Vec::new();
        }
        let identified: Vec<(u64, Result<ManifestRecord, String>)> = rows
            .into_par_iter()
            .map(|(n, r)| (n, identify(r).map_err(|e| format!("row {n}: {e}"))))
            .collect();
        let mut out = Vec::with_capacity(identified.len());
        for (n, record) in identified {
            match record {
                Ok(record) => self.keep(n, record, &mut out),
                Err(e) => self.unreadable.add(|| e, LISTED),
            }
        }
        if self.failed() {
            out.clear();
        }
        out
    }

    /// Keeps `record` (row `n`) in `out` unless its id is known or seen.
    fn keep(&mut self, n: u64, mut record: ManifestRecord, out: &mut Vec<ManifestRecord>) {
        let key = id_key(&record.id);
        if self.known.contains(&key) {
            self.already += 1;
            return;
        }
        if let Some(first) = self.seen.get(&key) {
            let first = *first;
            self.duplicates
                .add(|| format!("{} (rows {first} and {n})", record.id), 5);
            return;
        }
        self.seen.insert(key, n);
        for name in &self.columns {
            record.extra.entry(name.clone()).or_default();
        }
        self.unchecked += u64::from(record.sha256.is_none());
        self.kept += 1;
        out.push(record);
    }

    /// Refuses the freeze if any row had a problem, naming them; otherwise what was frozen,
    /// saying how many items have no sha256 to check their file against.
    pub fn finish(self) -> Result<Frozen> {
        if self.bad_sha.count() > 0 {
            bail!(
                "{} rows have a sha256 that is not 64 hex digits (a file's bytes are checked \
                 against it before they are converted): {}",
                self.bad_sha.count(),
                self.bad_sha.listing()
            );
        }
        if self.unreadable.count() > 0 {
            bail!(
                "{} of {} files could not be hashed for their ids (a row without id or sha256 \
                 is identified by its file's sha256): {}",
                self.unreadable.count(),
                self.rows,
                self.unreadable.listing()
            );
        }
        if self.duplicates.count() > 0 {
            bail!(
                "the manifest has {} duplicate ids, e.g. {}; ids must be unique",
                self.duplicates.count(),
                self.duplicates.listed().join(", ")
            );
        }
        note_unchecked(self.unchecked);
        Ok(Frozen {
            rows: self.rows,
            items: self.kept,
            already: self.already,
        })
    }
}

/// Says how many items have no sha256 to check their file against before it is converted.
fn note_unchecked(unchecked: u64) {
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

/// A row's record with its id and frozen sha256: the manifest's own, or (a row with neither)
/// the sha256 of the file, and an id made of it (and, for a local file that names others,
/// of those: [`crate::source_id`]).
fn identify(r: RawRecord) -> Result<ManifestRecord> {
    let (id, sha256) = match (r.id, r.sha256) {
        (Some(id), sha) => (id, sha),
        (None, Some(sha)) => (sha.clone(), Some(sha)),
        (None, None) => {
            let sha = crate::hash::source_sha256(&r.uri)?;
            (local_id(&r.uri, &sha)?, Some(sha))
        }
    };
    Ok(ManifestRecord {
        id,
        uri: r.uri,
        sha256,
        format: r.format,
        extra: r.extra,
    })
}

/// The id of a row without one whose source hashes to `sha`: [`crate::source_id`] for a local
/// file, the sha256 alone for a remote one.
fn local_id(uri: &str, sha: &str) -> Result<String> {
    match sparc3d_sources::Location::parse(uri)? {
        sparc3d_sources::Location::Local(path) => Ok(crate::source_id::source_id(&path, sha)?),
        sparc3d_sources::Location::Remote(_) => Ok(sha.to_string()),
    }
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

    /// Rows of a growing job: those with a known id left out and counted, the job's
    /// provenance columns given to the new ones, a repeated id refused naming both rows.
    #[test]
    fn a_growing_freeze_skips_known_ids_and_refuses_repeats() -> Result<()> {
        let mut first = Freezer::new();
        let records = first.batch(
            [row("a", Some("cc0")), row("b", None), row("c", None)]
                .into_iter()
                .enumerate()
                .map(|(i, r)| (i as u64 + 1, r))
                .collect(),
        );
        assert_eq!(first.finish()?.items, 3);
        let known: HashSet<IdKey> = records.iter().map(|r| id_key(&r.id)).collect();
        let columns: BTreeSet<String> = ["license".to_string()].into();
        let grow = |rows: Vec<RawRecord>| {
            let mut f = Freezer::growing(known.clone(), columns.clone());
            let kept = f.batch(rows.into_iter().zip(1..).map(|(r, n)| (n, r)).collect());
            f.finish().map(|frozen| (kept, frozen))
        };
        let (kept, frozen) = grow(vec![row("b", None), row("d", None), row("e", None)])?;
        assert_eq!((frozen.items, frozen.already), (2, 1));
        let ids: Vec<&str> = kept.iter().map(|r| r.id.as_str()).collect();
        assert_eq!(ids, ["d", "e"]);
        assert_eq!(kept[0].extra.get("license").map(String::as_str), Some(""));
        let refused = grow(vec![row("x", None), row("x", None)])
            .err()
            .map(|e| e.to_string());
        assert!(
            refused
                .as_deref()
                .is_some_and(|e| e.contains("x (rows 1 and 2)")),
            "{refused:?}"
        );
        let (kept, frozen) = grow(vec![row("a", None)])?;
        assert!(kept.is_empty() && frozen.already == 1);
        Ok(())
    }
}
