//! `sparc3d init JOB --manifest M [--for CONSUMER] [--resolution N] [--shard-size S]
//! [--config job.toml] [--path-column NAME] [--where FILTER]`: freezes the manifest into the job
//! folder as it reads it (`job/create.rs`: slices of the frozen manifest, one a shard), gives every
//! item its shard once, and writes the config with its fingerprint. Re-running with another
//! config is refused, naming the keys; a job whose files were edited since is refused too.
//! The command only reads its flags: the config, the rows and the job folder (or bucket) are
//! the job home's (`job/`).

use crate::flags::config::ConfigArgs;
use crate::flags::source::SourceArgs;
use crate::job::config::build_config;
use crate::job::create::create;
use crate::job::rows::InputRows;
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d init`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder to create, or a bucket prefix (s3://, gs://, az://) to make the job's home.
    pub job: PathBuf,
    /// Manifest (.csv, .jsonl or .parquet with a path column).
    #[arg(long)]
    pub manifest: PathBuf,
    #[command(flatten)]
    pub source: SourceArgs,
    #[command(flatten)]
    pub config: ConfigArgs,
}

/// Runs `sparc3d init`.
pub fn run(args: Args) -> Result<ExitCode> {
    let config = build_config(&args.config)?;
    let home = sparc3d_bucket::JobHome::parse(&args.job)?;
    if args.manifest.is_dir() {
        anyhow::bail!(
            "{}: --manifest takes a manifest file (.csv, .jsonl or .parquet); for a folder of \
             meshes: `sparc3d run {} --job {}`",
            args.manifest.display(),
            args.manifest.display(),
            args.job.display()
        );
    }
    let rows = InputRows::open(&args.manifest, &args.source)?;
    match home {
        sparc3d_bucket::JobHome::Folder(dir) => create(&dir, rows, config)?,
        sparc3d_bucket::JobHome::Bucket(url) => crate::job::bucket_home::init(&url, rows, config)?,
    }
    Ok(ExitCode::SUCCESS)
}
