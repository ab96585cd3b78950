//! `sparc3d validate JOB [--sample 2%|N] [--seed S] [--json]`: checks a reproducible sample of
//! a job's `ok` items with pymeshlab (docs/VALIDATION.md; the logic is `validation.rs`).
//!
//! Each sampled row is decoded (the same decode as `show`), its mesh extracted in the source
//! frame and written to a temporary PLY next to a PLY of the source as `sparc3d` loads it
//! (node transforms applied). One Python process (`pipeline/validate/validate.py`, built into the
//! binary) checks the whole sample, one JSON line in and one out per item: boundary edges,
//! non-manifold edges and vertices, orientation, volume, components, and the Hausdorff
//! distance both ways. The report goes to `JOB/validation/report.jsonl` and
//! `JOB/validation/summary.md`; the exit code is 1 when any check failed.

use crate::check::validation::{validate_job, NoPymeshlab, Options};
use crate::rows::sample::SampleSize;
use anyhow::Result;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Exit code when no Python with pymeshlab was found (checks failing give 1).
const EXIT_NO_PYMESHLAB: u8 = 2;

/// Arguments of `sparc3d validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder.
    pub job: PathBuf,
    /// How many `ok` items to check: a percentage (`2%`) or a count (`50`). Default: the job's
    /// `validation_sample_rate` (1% unless its config sets another), but at least 20 items
    /// (all of them when there are fewer).
    #[arg(long)]
    pub sample: Option<SampleSize>,
    /// Seed of the sample: the same seed gives the same items whatever the worker count.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Largest Hausdorff distance (either way, in voxels of the job's grid) that passes.
    #[arg(long, default_value_t = Options::default().max_hausdorff_voxels)]
    pub max_hausdorff_voxels: f64,
    /// Points sampled on each mesh for the Hausdorff distance (plus its vertices).
    #[arg(long, default_value_t = Options::default().hausdorff_samples)]
    pub hausdorff_samples: usize,
    /// Print the summary as one line of JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `sparc3d validate`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    let options = Options {
        sample: args.sample,
        seed: args.seed,
        max_hausdorff_voxels: args.max_hausdorff_voxels,
        hausdorff_samples: args.hausdorff_samples,
    };
    let outcome = match validate_job(&args.job, &options) {
        Ok(o) => o,
        Err(e) => match e.downcast_ref::<NoPymeshlab>() {
            Some(msg) => {
                eprintln!("error: {msg}");
                return Ok(ExitCode::from(EXIT_NO_PYMESHLAB));
            }
            None => return Err(e),
        },
    };
    if args.json {
        println!("{}", serde_json::to_string(&outcome.summary)?);
    }
    Ok(if outcome.failed > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// The hook of `sparc3d run --validate-sample`: validates a finished run's job with default
/// options and the given sample size; the exit code is that of `sparc3d validate`.
pub fn after_run(job: &Path, sample: SampleSize) -> Result<ExitCode> {
    run(Args {
        job: job.to_path_buf(),
        sample: Some(sample),
        seed: Options::default().seed,
        max_hausdorff_voxels: Options::default().max_hausdorff_voxels,
        hausdorff_samples: Options::default().hausdorff_samples,
        json: false,
    })
}
