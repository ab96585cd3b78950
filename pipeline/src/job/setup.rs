//! The job folder `sparc3d run` works on: an existing job, or (with `--job OUT`) one made from
//! a folder of meshes or a manifest when OUT is not a job yet, with `init`'s config flags, or
//! grown with what the folder or manifest has that it does not ([`grow`]) when it is; and the
//! job a read-only command opens ([`open_read_only`]).

use super::config::{build_config, check_same_config};
use super::create::{create, is_job};
use super::grow;
use super::rows::InputRows;
use crate::flags::config::ConfigArgs;
use crate::flags::source::SourceArgs;
use anyhow::{bail, Result};
use sparc3d_schema::JobLayout;
use sparc3d_workers::Job;
use std::path::{Path, PathBuf};

/// The job to run: `input` itself when `out` is `None` (it must be a job), else `out`,
/// grown with the new items of `input` and resumed when it is a job already, and otherwise
/// created from `input` (a folder of meshes, scanned as `manifest build` does, or a
/// manifest). Config flags given for an existing job must agree with its config.
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
        grow_before_run(input, out, source)?;
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
    create(out, InputRows::open(input, source)?, config)?;
    Ok(out.to_path_buf())
}

/// Adds what `input` has that the job `out` does not, saying what is new, before `out` is
/// resumed; when another run holds the job, says that nothing is added now and resumes.
fn grow_before_run(input: &Path, out: &Path, source: &SourceArgs) -> Result<()> {
    let _lock = match grow::lock_for_add(out) {
        Ok(lock) => lock,
        Err(e) => {
            eprintln!("note: {e:#}; resuming it as it is");
            return Ok(());
        }
    };
    let grown = grow::add(out, InputRows::open(input, source)?)?;
    eprintln!("{}; resuming the job", grow::describe(out, &grown));
    Ok(())
}

/// Refuses config flags that disagree with the existing job at `dir`.
fn check_flags(dir: &Path, flags: &ConfigArgs) -> Result<()> {
    if flags.any() {
        check_same_config(&Job::open(dir)?, &build_config(flags)?)?;
    }
    Ok(())
}

/// The job lock of `root` held shared for a command that converts (`run`, `work`), so that no
/// `add` changes the frozen manifest under it; waits, saying so, while an `add` holds it.
/// `None` when `root` is not a job (opening it says so next), or when the file system refuses
/// locks (some network file systems; said on stderr: the lock is advisory, the command goes
/// on).
pub fn hold_shared(root: &Path) -> Result<Option<sparc3d_workers::job::lock::JobLock>> {
    if !is_job(root) {
        return Ok(None);
    }
    let layout = JobLayout::new(root);
    let waiting = || eprintln!("{}: waiting for an `add` to finish", root.display());
    match sparc3d_workers::job::lock::JobLock::shared(&layout, waiting) {
        Ok(lock) => Ok(Some(lock)),
        Err(e) => {
            eprintln!("warning: {e}: going on without the job lock (an `add` is not kept out)");
            Ok(None)
        }
    }
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
