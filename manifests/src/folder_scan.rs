//! The meshes below a folder: every supported mesh file found recursively ([`scan`]), and
//! those files hashed with identical duplicates dropped ([`collect`], what `manifest build`
//! and `run DIR --job OUT` freeze).

use crate::record::ManifestRecord;
use anyhow::{Context, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Collects the mesh files below `dir`, recursively, in name order: files with a supported
/// extension that are regular files once links are followed. A FIFO, device or socket with a
/// mesh extension (or a link to one, or a dangling link) is skipped, and so is a file or
/// folder whose name is not UTF-8 (a manifest could not keep it exactly); each skip is
/// printed with the name (non-UTF-8 bytes escaped) and counted. Returns the count.
pub fn scan(dir: &Path, out: &mut Vec<PathBuf>) -> Result<u64> {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .with_context(|| format!("reading folder {}", dir.display()))?
        .filter_map(|e| e.ok())
        .collect();
    entries.sort_by_key(|e| e.file_name());
    let mut skipped = 0;
    for e in entries {
        let path = e.path();
        let Ok(kind) = e.file_type() else { continue };
        let is_mesh = sparcubes::io::Format::from_extension(&path).is_some();
        if !(kind.is_dir() || is_mesh) {
            continue;
        }
        if e.file_name().to_str().is_none() {
            eprintln!("skipping {path:?}: the name is not UTF-8 (rename it to convert it)");
            skipped += 1;
        } else if kind.is_dir() {
            skipped += scan(&path, out)?;
        } else {
            match sparcubes::io::open_regular(&path) {
                Ok(_) => out.push(path),
                Err(err) => {
                    eprintln!("skipping {}: {err}", path.display());
                    skipped += 1;
                }
            }
        }
    }
    Ok(skipped)
}

/// The meshes found below a folder: one record per distinct source (id: the mesh file's
/// sha256, with the files it names when it names any, [`crate::source_id`]), and what was
/// left out.
pub struct Collected {
    /// Records in name order.
    pub records: Vec<ManifestRecord>,
    /// Files identical to an earlier one (left out).
    pub duplicates: usize,
    /// Files that could not be read.
    pub unreadable: usize,
    /// Entries skipped by [`scan`].
    pub skipped: u64,
}

/// Scans `dir` for meshes, hashes them in parallel and drops identical duplicates (the same
/// mesh file naming the same files, [`crate::source_id`]), printing each file left out on
/// stderr.
pub fn collect(dir: &Path) -> Result<Collected> {
    let root =
        std::fs::canonicalize(dir).with_context(|| format!("opening folder {}", dir.display()))?;
    let mut files = Vec::new();
    let skipped = scan(&root, &mut files)?;
    let hashed: Vec<(PathBuf, Result<(String, String)>)> = files
        .into_par_iter()
        .map(|p| {
            let h = identify(&p);
            (p, h)
        })
        .collect();
    let mut records = Vec::new();
    let mut seen: HashMap<String, PathBuf> = HashMap::new();
    let (mut duplicates, mut unreadable) = (0usize, 0usize);
    for (path, hash) in hashed {
        let (id, sha) = match hash {
            Ok(h) => h,
            Err(e) => {
                eprintln!("skipping unreadable file: {e:#}");
                unreadable += 1;
                continue;
            }
        };
        if let Some(first) = seen.get(&id) {
            eprintln!(
                "duplicate: {} is identical to {}",
                path.display(),
                first.display()
            );
            duplicates += 1;
            continue;
        }
        seen.insert(id.clone(), path.clone());
        records.push(ManifestRecord {
            id,
            uri: path.to_string_lossy().into_owned(),
            sha256: Some(sha),
            format: path
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase()),
            extra: Default::default(),
        });
    }
    Ok(Collected {
        records,
        duplicates,
        unreadable,
        skipped,
    })
}

/// The id and sha256 of the mesh file at `path`.
fn identify(path: &Path) -> Result<(String, String)> {
    let sha = crate::hash::file_sha256(path)?;
    Ok((crate::source_id::source_id(path, &sha)?, sha))
}
