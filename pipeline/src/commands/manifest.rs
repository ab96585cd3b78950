//! `sparc3d manifest build DIR -o manifest.(parquet|jsonl|csv)`: scan a folder for supported
//! meshes, hash them in parallel, and report identical duplicates (kept once).

use crate::manifest_io;
use anyhow::{Context, Result};
use rayon::prelude::*;
use sparc3d_schema::ManifestRecord;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d manifest`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Scan a folder for meshes and write a manifest (id = sha256 of the file).
    Build(BuildArgs),
}

/// Arguments of `sparc3d manifest build`.
#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Folder to scan (recursively).
    pub dir: PathBuf,
    /// Output manifest (.parquet, .jsonl or .csv).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Collects the supported mesh files below `dir`, recursively, in name order.
pub(crate) fn scan(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .with_context(|| format!("reading folder {}", dir.display()))?
        .filter_map(|e| e.ok())
        .collect();
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let path = e.path();
        let Ok(kind) = e.file_type() else { continue };
        if kind.is_dir() {
            scan(&path, out)?;
        } else if sparcubes::io::Format::from_extension(&path).is_some() {
            out.push(path);
        }
    }
    Ok(())
}

/// Runs `sparc3d manifest`.
pub fn run(args: Args) -> Result<ExitCode> {
    let Sub::Build(args) = args.command;
    let root = std::fs::canonicalize(&args.dir)
        .with_context(|| format!("opening folder {}", args.dir.display()))?;
    let mut files = Vec::new();
    scan(&root, &mut files)?;
    let hashed: Vec<(PathBuf, Result<String>)> = files
        .into_par_iter()
        .map(|p| {
            let h = manifest_io::file_sha256(&p);
            (p, h)
        })
        .collect();
    let mut records = Vec::new();
    let mut seen: HashMap<String, PathBuf> = HashMap::new();
    let (mut duplicates, mut unreadable) = (0usize, 0usize);
    for (path, hash) in hashed {
        let sha = match hash {
            Ok(h) => h,
            Err(e) => {
                eprintln!("skipping unreadable file: {e:#}");
                unreadable += 1;
                continue;
            }
        };
        if let Some(first) = seen.get(&sha) {
            eprintln!(
                "duplicate: {} is identical to {}",
                path.display(),
                first.display()
            );
            duplicates += 1;
            continue;
        }
        seen.insert(sha.clone(), path.clone());
        records.push(ManifestRecord {
            id: sha.clone(),
            uri: path.to_string_lossy().into_owned(),
            sha256: Some(sha),
            format: path
                .extension()
                .map(|e| e.to_string_lossy().to_ascii_lowercase()),
        });
    }
    manifest_io::write(&records, &args.output)?;
    eprintln!(
        "{} meshes written to {} ({duplicates} identical duplicates left out, {unreadable} unreadable)",
        records.len(),
        args.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
