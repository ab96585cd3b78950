//! `sparc3d init JOB --manifest M [--for CONSUMER] [--resolution N] [--shard-size S]
//! [--config job.toml] [--path-column NAME] [--where FILTER]`: freezes the manifest into the job folder (`sparc3d_manifests::freeze`), gives every
//! item its shard once, and writes the config with its fingerprint. Re-running with another
//! config is refused, naming the keys; a job whose files were edited since is refused too.
//! The command only reads its flags: the config, the rows and the job folder (or bucket) are
//! the job home's (`job/`).

use crate::flags::config::ConfigArgs;
use crate::flags::source::SourceArgs;
use crate::job::config::build_config;
use crate::job::create::create;
use crate::job::rows::read_manifest;
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
    let records = read_manifest(&args.manifest, &args.source)?;
    match sparc3d_bucket::JobHome::parse(&args.job)? {
        sparc3d_bucket::JobHome::Folder(dir) => create(&dir, records, config)?,
        sparc3d_bucket::JobHome::Bucket(url) => {
            crate::job::bucket_home::init(&url, records, config)?
        }
    }
    Ok(ExitCode::SUCCESS)
}
