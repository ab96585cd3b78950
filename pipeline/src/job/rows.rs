//! The rows a job is made or grown from: a manifest read with `--path-column` and `--where`
//! (saying which column its paths came from and what `--where` left out), or a folder of
//! meshes scanned as `manifest build` does.

use crate::flags::source::SourceArgs;
use anyhow::{bail, Result};
use sparc3d_manifests::filter::Filter;
use sparc3d_manifests::folder_scan::collect;
use sparc3d_manifests::table as manifest_io;
use sparc3d_manifests::RawRecord;
use std::path::Path;

/// The rows of `input`: a folder scanned as `manifest build` does, or a manifest read as
/// `init` reads it (with `--path-column` and `--where`).
pub fn input_records(input: &Path, source: &SourceArgs) -> Result<Vec<RawRecord>> {
    if !input.is_dir() {
        return read_manifest(input, source);
    }
    let c = collect(input)?;
    eprintln!(
        "{}: {} meshes ({} identical duplicates left out, {} unreadable, {} skipped)",
        input.display(),
        c.records.len(),
        c.duplicates,
        c.unreadable,
        c.skipped
    );
    let records = c.records.into_iter().map(RawRecord::from).collect();
    select(records, source, input)
}

/// Reads a manifest's rows for a job, saying which column its paths came from, which
/// provenance columns it keeps and how many rows `--where` left out; an empty manifest (or
/// one that `--where` empties) is refused.
pub fn read_manifest(path: &Path, source: &SourceArgs) -> Result<Vec<RawRecord>> {
    let manifest = manifest_io::read(path, source.path_column.as_deref())?;
    if manifest.records.is_empty() {
        bail!("{}: the manifest is empty", path.display());
    }
    eprintln!(
        "{}: {} rows, paths from column {} ({})",
        path.display(),
        manifest.records.len(),
        manifest.path_column.name,
        manifest.path_column.why
    );
    if let Some(first) = manifest.records.first().filter(|r| !r.extra.is_empty()) {
        let names: Vec<&str> = first.extra.keys().map(String::as_str).collect();
        eprintln!(
            "{}: provenance columns kept with every item: {}",
            path.display(),
            names.join(", ")
        );
    }
    select(manifest.records, source, path)
}

/// The rows of `input` (a manifest or a folder) that pass `--where`, saying how many it left
/// out; all of them without `--where`. Refused when none passes.
pub fn select(
    records: Vec<RawRecord>,
    source: &SourceArgs,
    input: &Path,
) -> Result<Vec<RawRecord>> {
    let Some(text) = &source.filter else {
        return Ok(records);
    };
    let (kept, left_out) = Filter::parse(text)?.apply(records)?;
    eprintln!(
        "{}: --where {text}: {} rows kept, {left_out} left out",
        input.display(),
        kept.len()
    );
    if kept.is_empty() {
        bail!("{}: no row passes --where {text}", input.display());
    }
    Ok(kept)
}
