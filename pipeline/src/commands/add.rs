//! `sparc3d add JOB (DIR | MANIFEST) [--path-column NAME] [--where FILTER]`: grows a job with
//! the items of a folder or manifest it does not have yet (by id), as new shards after its
//! last one (`job/grow.rs`); `sparc3d run JOB` then converts them. Refused at once, with nothing
//! changed, while a `run` or `work` holds the job or another `add` runs.

use crate::flags::source::SourceArgs;
use crate::job::grow;
use crate::job::rows::InputRows;
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d add`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder to grow.
    pub job: PathBuf,
    /// A folder of meshes (scanned as `manifest build` does) or a manifest.
    #[arg(value_name = "DIR|MANIFEST")]
    pub input: PathBuf,
    #[command(flatten)]
    pub source: SourceArgs,
}

/// Runs `sparc3d add`.
pub fn run(args: Args) -> Result<ExitCode> {
    crate::job::bucket_home::refuse(&args.job, "`add` (growing a job) is not available")?;
    let _lock = grow::lock_for_add(&args.job)?;
    let grown = grow::add(&args.job, InputRows::open(&args.input, &args.source)?)?;
    eprintln!("{}", grow::describe(&args.job, &grown));
    if grown.added > 0 {
        eprintln!("next: sparc3d run {}", args.job.display());
    }
    Ok(ExitCode::SUCCESS)
}
