//! The job folder `sparc3d run` works on: an existing job, or (with `--job OUT`) one made from
//! a folder of meshes or a manifest when OUT is not a job yet, with `init`'s config flags; and
//! the job a read-only command opens ([`open_read_only`]).

use crate::commands::init::{
    build_config, check_same_config, create, read_manifest, select, ConfigArgs, SourceArgs,
};
use anyhow::{bail, Result};
use sparc3d_manifests::folder_scan::collect;
use sparc3d_manifests::RawRecord;
use sparc3d_schema::JobLayout;
use sparc3d_workers::Job;
use std::path::{Path, PathBuf};

/// Whether `dir` is a job folder (it has its job file).
fn is_job(dir: &Path) -> bool {
    JobLayout::new(dir).job_file().exists()
}

/// The job to run: `input` itself when `out` is `None` (it must be a job), else `out`,
/// resumed when it is a job already and otherwise created from `input` (a folder of meshes,
/// scanned as `manifest build` does, or a manifest). Config flags given for an existing job
/// must agree with its config.
pub fn job_for_run(
    input: &Path,
    out: Option<&Path>,
    flags: &ConfigArgs,
    source: &SourceArgs,
) -> Result<PathBuf> {
    let Some(out) = out else {
        if !is_job(input) {
            bail!(
                "{} is not a job folder (it has no job.json); to make a job of a folder of meshes \
                 or a manifest and run it: `sparc3d run {} --job OUT`",
                input.display(),
                input.display()
            );
        }
        check_flags(input, flags)?;
        return Ok(input.to_path_buf());
    };
    if is_job(out) {
        check_flags(out, flags)?;
        eprintln!(
            "{}: resuming this job (its manifest was frozen when it was made; for files added to \
             {} since, use a new --job)",
            out.display(),
            input.display()
        );
        return Ok(out.to_path_buf());
    }
    if is_job(input) {
        bail!(
            "{} is a job folder already: run it with `sparc3d run {}`",
            input.display(),
            input.display()
        );
    }
    let config = build_config(flags)?;
    let records: Vec<RawRecord> = if input.is_dir() {
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
        select(records, source, input)?
    } else {
        read_manifest(input, source)?
    };
    if records.is_empty() {
        bail!("{}: no meshes to convert", input.display());
    }
    create(out, records, config)?;
    Ok(out.to_path_buf())
}

/// Refuses config flags that disagree with the existing job at `dir`.
fn check_flags(dir: &Path, flags: &ConfigArgs) -> Result<()> {
    if flags.any() {
        check_same_config(&Job::open(dir)?, &build_config(flags)?)?;
    }
    Ok(())
}

/// Opens the job at `root` for a command that only reads it (`status`, `ls`, `failures`,
/// `inspect`, `show`, ...): a job whose files were edited after `init` is opened all the same,
/// after a warning on stderr naming each file and what differs; commands that change a job
/// refuse it ([`Job::open`]).
pub fn open_read_only(root: &Path) -> Result<Job> {
    let (job, problems) = Job::open_read_only(root)?;
    for p in &problems {
        eprintln!("warning: {}: {p}", root.display());
    }
    if !problems.is_empty() {
        eprintln!(
            "warning: {} was changed after `sparc3d init`: what follows is read as it is, and \
             commands that change the job (run, work, retry, verify, submit) refuse it",
            root.display()
        );
    }
    Ok(job)
}
