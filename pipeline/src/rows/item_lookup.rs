//! Finding a job's item from what a user types after `--id`: the whole id, a unique prefix of
//! it, or the item's source file (its path, or a trailing part of it such as the file name).
//! A miss suggests the closest ids and file names; an ambiguous prefix or name lists its
//! matches. Every command that names items (`show --id`, `preview --id`, `export --ids`) goes
//! through [`find`].

use anyhow::{bail, Context, Result};
use sparc3d_schema::{FrozenItem, ShardRow};
use sparc3d_workers::store::read::shard_rows;
use sparc3d_workers::store::state::Check;
use sparc3d_workers::Job;

/// How many matches or suggestions an error lists.
const LISTED: usize = 5;

/// The item `query` names: its id, a prefix of its id that no other item has, or its source
/// file (the path as in the manifest, a path to the same file, or the path's last components,
/// e.g. the file name) when no other item has it. An exact id wins over everything else.
pub fn find(job: &Job, query: &str) -> Result<FrozenItem> {
    let q = query.trim();
    let root = job.layout.root.display();
    if q.is_empty() {
        bail!("an empty --id names no item; `sparc3d ls {root}` lists the items with their ids");
    }
    let canonical = std::fs::canonicalize(q)
        .ok()
        .map(|p| p.to_string_lossy().into_owned());
    // One pass over the items, a shard at a time: an exact id ends it; a few matches are kept.
    let mut matches: Vec<FrozenItem> = Vec::new();
    for item in job.items() {
        let item = item?;
        if item.record.id == q {
            return Ok(item);
        }
        let matching =
            item.record.id.starts_with(q) || is_source(&item.record.uri, q, canonical.as_deref());
        if matching && matches.len() < 64 {
            matches.push(item);
        }
    }
    match matches.as_slice() {
        [one] => Ok(one.clone()),
        [] => bail!(
            "no item of {root} matches --id {q:?} (not an id, a unique id prefix or a source \
             file){}; `sparc3d ls {root}` lists every item with its id",
            suggestions(job, q)
        ),
        many => bail!(
            "--id {q:?} is ambiguous: {} items of {root} match ({}{}); give more of the id",
            many.len(),
            many.iter()
                .take(LISTED)
                .map(describe)
                .collect::<Vec<_>>()
                .join(", "),
            if many.len() > LISTED { ", …" } else { "" }
        ),
    }
}

/// The converted row of `item`, from its shard (finished, its record hashed first, or in
/// progress).
pub fn row(job: &Job, item: &FrozenItem) -> Result<ShardRow> {
    let id = &item.record.id;
    shard_rows(job, item.shard, Check::Full)?
        .into_iter()
        .find(|r| &r.id == id)
        .with_context(|| {
            format!(
                "item {id:?} ({}, shard {}) is not converted yet",
                item.record.uri, item.shard
            )
        })
}

/// The sparse cubes of a converted row; a failed row's error names the item and its failure.
pub fn cubes(row: &ShardRow) -> Result<sparcubes::SparseCubes> {
    row.cubes().with_context(|| {
        format!(
            "item {:?}: {}",
            row.id,
            row.error_message.clone().unwrap_or_default()
        )
    })
}

/// Whether `query` names the source `uri`: the same text, the same file once resolved, or
/// the uri's last path components.
fn is_source(uri: &str, query: &str, canonical: Option<&str>) -> bool {
    uri == query
        || canonical == Some(uri)
        || (uri.ends_with(query) && uri[..uri.len() - query.len()].ends_with('/'))
}

/// An item as listed in errors: its id and source.
fn describe(item: &FrozenItem) -> String {
    format!("{} {}", item.record.id, item.record.uri)
}

/// "; closest: …" with the items whose id start or file name is nearest to `query` in edit
/// distance (case ignored), or nothing when none is near.
fn suggestions(job: &Job, query: &str) -> String {
    let q = query.to_lowercase();
    let limit = (q.chars().count() / 3).max(2);
    // Streamed a slice at a time: only the near items are kept, never the whole manifest.
    let mut near: Vec<(usize, FrozenItem)> = job
        .items()
        .filter_map(|i| i.ok())
        .filter_map(|i| {
            let id: String = i
                .record
                .id
                .to_lowercase()
                .chars()
                .take(q.chars().count())
                .collect();
            let name = i.record.uri.rsplit('/').next().unwrap_or("").to_lowercase();
            let d = edit_distance(&q, &id).min(edit_distance(&q, &name));
            (d <= limit).then_some((d, i))
        })
        .collect();
    near.sort_by_key(|(d, i)| (*d, i.index));
    if near.is_empty() {
        return String::new();
    }
    let listed: Vec<String> = near.iter().take(LISTED).map(|(_, i)| describe(i)).collect();
    format!("; closest: {}", listed.join(", "))
}

/// Levenshtein distance between two strings, by characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.chars().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let substitute = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = substitute.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance_counts_single_character_edits() {
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("wuson.stl", "wuson.stl"), 0);
        assert_eq!(edit_distance("wusn.stl", "wuson.stl"), 1);
        assert_eq!(edit_distance("e14e697b2b35", "e14e697b2b34"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }

    #[test]
    fn a_source_matches_whole_or_by_trailing_components() {
        let uri = "/data/meshes/wuson.stl";
        assert!(is_source(uri, uri, None));
        assert!(is_source(uri, "wuson.stl", None));
        assert!(is_source(uri, "meshes/wuson.stl", None));
        assert!(!is_source(uri, "son.stl", None), "only whole components");
        assert!(is_source(uri, "./wuson.stl", Some(uri)));
    }
}
