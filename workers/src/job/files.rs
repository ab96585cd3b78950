//! Whether a job's own files are as `sparc3d init` wrote them. `init` records the config's
//! fingerprint and the frozen manifest's sha256 in `job.json` (with the sha256 of each index
//! page of a sliced manifest, each page those of its slices); a hand edit (a resolution, a
//! shard size, a path in a slice) no longer matches what was recorded, and a config out of
//! range fails every item. [`job_file_problems`], [`pin_problems`] and
//! [`whole_manifest_problems`] name each such finding with its file and what differs (a
//! slice's own is found when it is read: [`crate::frozen::sliced`]); [`crate::Job::open`]
//! refuses a job with any, and read-only commands open it with
//! [`crate::Job::open_read_only`] and say what was found.

use crate::frozen::Sliced;
use crate::store::footer::read_meta;
use sparc3d_schema::job::manifest::index_sha256;
use sparc3d_schema::{meta_keys, FrozenItem, JobConfig, JobFile, JobLayout, SCHEMA_VERSION};

/// What differs between `job.json` (read as `file`) and what `init` recorded, one line each
/// naming the file; empty when it is as `init` wrote it. Reads no manifest.
pub fn job_file_problems(layout: &JobLayout, file: &JobFile) -> Vec<String> {
    let mut out = Vec::new();
    if file.schema_version != SCHEMA_VERSION {
        out.push(format!(
            "job.json: schema_version is {}, this sparc3d writes version {SCHEMA_VERSION} \
             (a job is never a mix of versions: convert it again in a new job folder)",
            file.schema_version
        ));
    }
    if let Err(e) = file.config.validate() {
        out.push(format!("job.json: {e}"));
    }
    if let Some(p) = fingerprint_problem(layout, file) {
        out.push(p);
    }
    out
}

/// What differs between the pages `job.json` pins (`sliced`'s) and its own counts and
/// `manifest_sha256`. Reads no slice: each is checked when read.
pub fn pin_problems(file: &JobFile, sliced: &Sliced) -> Vec<String> {
    let mut out = sliced.pin_problems(file);
    let root = index_sha256(sliced.pages());
    if root != file.manifest_sha256 {
        out.push(format!(
            "job.json: its manifest_pages give index sha256 {root}, but it records \
             manifest_sha256 {}: job.json was edited after `sparc3d init`",
            file.manifest_sha256
        ));
    }
    out
}

/// What differs between a job's frozen manifest in one file (`manifest.jsonl`, made before
/// slices) and what `init` recorded: its sha256, the shard count, the shards' layout.
/// `items` were read from `manifest_bytes`.
pub fn whole_manifest_problems(
    file: &JobFile,
    items: &[FrozenItem],
    manifest_bytes: &[u8],
) -> Vec<String> {
    let mut out = Vec::new();
    let size = u64::from(file.config.shard_size.max(1));
    let shards = items.last().map_or(0, |i| i.shard + 1);
    if file.shards != shards {
        out.push(format!(
            "job.json: shards is {}, but the frozen manifest's items are in {shards}",
            file.shards
        ));
    }
    let sha = crate::fsutil::bytes_sha256(manifest_bytes);
    if sha != file.manifest_sha256 {
        out.push(format!(
            "manifest.jsonl: its sha256 is {sha}, but job.json recorded {} when the manifest was \
             frozen: the frozen manifest was edited after `sparc3d init` (its paths, ids and \
             shards never change once frozen)",
            file.manifest_sha256
        ));
    }
    if let Some(p) = shard_layout_problem(items, size) {
        out.push(p);
    }
    out
}

/// Whether the items' shards are a layout `init` and `add` make: shard 0 first, each item in
/// its predecessor's shard or the next, at most `size` items a shard (a job made at once has
/// `index / size`; each `add` starts a new shard).
fn shard_layout_problem(items: &[FrozenItem], size: u64) -> Option<String> {
    let mut count = 0u64;
    let mut previous: Option<u64> = None;
    for item in items {
        let expected_next = previous.map_or(0, |p| p + 1);
        let ok = match previous {
            Some(p) if item.shard == p => {
                count += 1;
                count <= size
            }
            _ => {
                count = 1;
                item.shard == expected_next
            }
        };
        if !ok {
            return Some(format!(
                "manifest.jsonl: item {} ({}) is in shard {}, which shards of {size} filled in \
                 order cannot give",
                item.index, item.record.id, item.shard
            ));
        }
        previous = Some(item.shard);
    }
    None
}

/// The finding when the stored config no longer gives the fingerprint recorded with it, with
/// the keys that differ from the config a finished shard was written with, when there is one.
fn fingerprint_problem(layout: &JobLayout, file: &JobFile) -> Option<String> {
    let now = match file.config.fingerprint() {
        Ok(f) if f == file.fingerprint => return None,
        Ok(f) => f,
        Err(e) => return Some(format!("job.json: the config cannot be fingerprinted: {e}")),
    };
    let short = |f: &str| f.chars().take(12).collect::<String>();
    let written = shard_config(layout, file.shards);
    let what = match written.map(|written| changed_keys(&written, &file.config)) {
        Some(keys) if !keys.is_empty() => keys,
        _ => format!(
            "it gives fingerprint {}…, init recorded {}… (no finished shard says which key \
             changed)",
            short(&now),
            short(&file.fingerprint)
        ),
    };
    Some(format!(
        "job.json: the config was edited after `sparc3d init`: {what}; a job's config never \
         changes (convert with another config in a new job folder)"
    ))
}

/// The config stored in the first of the job's `shards` shard files that has one (Parquet
/// key-value metadata), if any.
fn shard_config(layout: &JobLayout, shards: u64) -> Option<JobConfig> {
    (0..shards).find_map(|shard| {
        let path = layout.shard_file(shard);
        if !path.exists() {
            return None;
        }
        let meta = read_meta(&path).ok()?;
        let text = meta.kv.get(meta_keys::CONFIG)?;
        serde_json::from_str(text).ok()
    })
}

/// The fingerprinted keys whose values differ, as `key: old → new`, comma-separated.
fn changed_keys(old: &JobConfig, new: &JobConfig) -> String {
    let (Ok(keys), Ok(a), Ok(b)) = (
        old.diff_keys(new),
        serde_json::to_value(old),
        serde_json::to_value(new),
    ) else {
        return String::new();
    };
    let value = |v: &serde_json::Value, key: &str| {
        let pointer = format!("/{}", key.replace('.', "/"));
        v.pointer(&pointer)
            .map_or("(none)".to_string(), |x| x.to_string())
    };
    keys.iter()
        .filter(|k| {
            !sparc3d_schema::job::config::UNFINGERPRINTED
                .iter()
                .any(|u| k.as_str() == *u || k.starts_with(&format!("{u}.")))
        })
        .map(|k| {
            let (was, now) = (value(&a, k), value(&b, k));
            format!("{k} is {now}, the shards were written with {was}")
        })
        .collect::<Vec<_>>()
        .join(", ")
}
