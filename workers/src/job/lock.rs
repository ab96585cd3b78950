//! The job lock (`JOB/job.lock`): what keeps a job's frozen manifest from changing under
//! a command that reads it. Commands that convert (`run`, `work`) hold it shared for as long as
//! they run; `add` (and `run DIR --job JOB` while it adds) holds it exclusive for the moment it
//! rewrites `manifest.jsonl` and `job.json`. An `add` that finds it held is refused at once,
//! saying why; a `run` or `work` that finds an `add` holding it waits the moment that takes.
//!
//! It is an advisory `flock(2)` on a file of its own, released by the kernel when the process
//! ends however it ends: no stale lock is ever left behind. `flock` does not reach other
//! machines on most network file systems, so `add` is not safe against workers elsewhere: stop
//! them first; where a file system refuses `flock` altogether, the commands say so and go on
//! without the lock.

use crate::error::{Result, WorkerError};
use sparc3d_schema::JobLayout;
use std::fs::{File, OpenOptions};
use std::os::fd::AsRawFd;

/// A held job lock; released when dropped.
#[derive(Debug)]
pub struct JobLock {
    file: File,
}

/// Opens (creating it when needed) the lock file of the job at `layout`.
fn open(layout: &JobLayout) -> Result<File> {
    let path = layout.job_lock();
    OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| WorkerError::io("opening the job lock", &path, e))
}

/// `flock(fd, op)`; `Ok(false)` when `LOCK_NB` was asked for and another holder has it.
fn flock(file: &File, op: libc::c_int, layout: &JobLayout) -> Result<bool> {
    // SAFETY: flock on a file descriptor this process owns for the call's duration.
    if unsafe { libc::flock(file.as_raw_fd(), op) } == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) {
        return Ok(false);
    }
    Err(WorkerError::io("locking the job", layout.job_lock(), e))
}

impl JobLock {
    /// The lock held exclusively, or `None` at once when a run, a worker or another add holds
    /// it.
    pub fn try_exclusive(layout: &JobLayout) -> Result<Option<Self>> {
        let file = open(layout)?;
        let held = flock(&file, libc::LOCK_EX | libc::LOCK_NB, layout)?;
        Ok(held.then_some(Self { file }))
    }

    /// The lock held shared (with other runs and workers); when an `add` holds it, calls
    /// `waiting` once and waits for it.
    pub fn shared(layout: &JobLayout, waiting: impl FnOnce()) -> Result<Self> {
        let file = open(layout)?;
        if !flock(&file, libc::LOCK_SH | libc::LOCK_NB, layout)? {
            waiting();
            flock(&file, libc::LOCK_SH, layout)?;
        }
        Ok(Self { file })
    }

    /// Turns an exclusive lock into a shared one (for `run DIR --job JOB` once it has added),
    /// waiting as [`JobLock::shared`] does if an `add` slips in between.
    pub fn downgrade(self, layout: &JobLayout) -> Result<Self> {
        flock(&self.file, libc::LOCK_SH, layout)?;
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_exclusive_holder_keeps_others_out_until_it_lets_go() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| WorkerError::io("tempdir", "/tmp", e))?;
        let layout = JobLayout::new(dir.path());
        crate::fsutil::create_dir(&layout.state_dir())?;
        let held = JobLock::try_exclusive(&layout)?;
        assert!(held.is_some());
        assert!(
            JobLock::try_exclusive(&layout)?.is_none(),
            "two adds at once"
        );
        drop(held);
        let shared = JobLock::shared(&layout, || panic!("nothing holds it"))?;
        let other = JobLock::shared(&layout, || panic!("shared locks share"))?;
        assert!(
            JobLock::try_exclusive(&layout)?.is_none(),
            "an add during a run"
        );
        drop((shared, other));
        assert!(JobLock::try_exclusive(&layout)?.is_some());
        Ok(())
    }
}
