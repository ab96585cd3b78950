//! `sparc3d manifest build (DIR | s3://bucket/prefix/) -o manifest.(parquet|jsonl|csv)`: scan
//! a folder, or list a bucket prefix, for supported meshes, hash them in parallel, and report
//! identical duplicates (kept once).

use anyhow::{bail, Result};
use sparc3d_manifests::bucket_scan::{self, IdFrom};
use sparc3d_manifests::folder_scan::collect;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d manifest`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Sub,
}

#[derive(Debug, clap::Subcommand)]
enum Sub {
    /// Scan a folder, or list a bucket prefix (s3://, gs://, az://), for meshes and write a
    /// manifest (id = sha256 of the file, unless --id-from says otherwise).
    Build(BuildArgs),
}

/// How a listed object's id is made (`--id-from`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum IdFromArg {
    /// The sha256 of the bytes: every object is downloaded and hashed.
    Sha256,
    /// The store's ETag: no download; not a content hash for multipart uploads.
    Etag,
    /// The object key: no download; names the object, not its content.
    Key,
}

/// Arguments of `sparc3d manifest build`.
#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Folder to scan (recursively), or a bucket prefix to list (s3://bucket/prefix/,
    /// gs://..., az://...).
    pub dir: String,
    /// Output manifest (.parquet, .jsonl or .csv).
    #[arg(short, long)]
    pub output: PathBuf,
    /// For a bucket prefix: ids from the bytes' sha256 (downloads every object), the ETag or
    /// the key (list only). Folders always hash.
    #[arg(long, value_enum, default_value = "sha256")]
    pub id_from: IdFromArg,
}

/// Runs `sparc3d manifest`.
pub fn run(args: Args) -> Result<ExitCode> {
    let Sub::Build(args) = args.command;
    let remote = sparc3d_sources::location::is_url(&args.dir);
    if !remote && args.id_from != IdFromArg::Sha256 {
        bail!("--id-from is for bucket prefixes; files in a folder are always identified by their sha256");
    }
    let c = if remote {
        let id_from = match args.id_from {
            IdFromArg::Sha256 => IdFrom::Sha256,
            IdFromArg::Etag => IdFrom::Etag,
            IdFromArg::Key => IdFrom::Key,
        };
        bucket_scan::collect(&args.dir, id_from)?
    } else {
        collect(std::path::Path::new(&args.dir))?
    };
    sparc3d_manifests::write::write(&c.records, &args.output)?;
    eprintln!(
        "{} meshes written to {} ({} identical duplicates left out, {} unreadable, {} \
         skipped: not regular files or names that are not UTF-8)",
        c.records.len(),
        args.output.display(),
        c.duplicates,
        c.unreadable,
        c.skipped
    );
    Ok(ExitCode::SUCCESS)
}
