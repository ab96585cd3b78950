//! The workers of `sparc3d run`: `sparc3d work JOB --shard-index I --events --parent-pid P`
//! processes on this machine, started and watched through the one child-process supervisor
//! (`sparc3d_workers::isolate::process`), their JSON-line events read into the pool's channel, their
//! share of the lanes written to their stdin (`--control-stdin`).

use crate::run::pool::{Launcher, Worker};
use anyhow::{Context, Result};
use sparc3d_workers::isolate::process::{Process, ProcessOptions};
use sparc3d_workers::lease::LeaseInfo;
use sparc3d_workers::shard::events::Event;
use sparc3d_workers::shard::lanes::Share;
use sparc3d_workers::store::state::{shard_state, Check, ShardState};
use sparc3d_workers::Job;
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Command, ExitStatus, Stdio};
use std::sync::mpsc::Sender;
use std::time::Duration;

/// Bytes of a worker's stderr kept to say why it failed.
const STDERR_TAIL_BYTES: usize = 8192;

/// Starts `work` processes for one job.
pub struct LocalWorkers<'a> {
    /// The job.
    pub job: &'a Job,
    /// Its folder, as given to the workers.
    pub job_dir: PathBuf,
    /// Extra arguments of every worker (the per-run limits).
    pub limit_args: Vec<String>,
    /// Threads per worker (`RAYON_NUM_THREADS`, unless the environment sets it).
    pub threads: usize,
}

/// A `work` process, and the pipe that gives it new shares.
pub struct WorkProcess(Process, Option<std::process::ChildStdin>);

impl Worker for WorkProcess {
    fn try_wait(&mut self) -> Option<ExitStatus> {
        self.0.try_wait()
    }

    fn terminate(&mut self) {
        self.0.signal(libc::SIGTERM);
    }

    /// SIGKILL, which also ends a stopped process; its item worker follows by its
    /// parent-death signal.
    fn kill(&mut self) {
        self.0.signal(libc::SIGKILL);
    }

    fn pid(&self) -> u32 {
        self.0.id()
    }

    /// Waits (briefly) until its stderr is read to the end, so that the reason a worker
    /// failed is never lost.
    fn error_tail(&mut self) -> String {
        self.0.wait_stderr_end(Some(Duration::from_secs(5)));
        self.0.stderr_tail(STDERR_TAIL_BYTES).trim().to_string()
    }

    /// One JSON line on its stdin; a worker that has exited no longer needs it.
    fn set_share(&mut self, share: Share) {
        let Some(pipe) = self.1.as_mut() else { return };
        let sent = serde_json::to_string(&share)
            .map_err(std::io::Error::other)
            .and_then(|line| writeln!(pipe, "{line}"))
            .and_then(|_| pipe.flush());
        if sent.is_err() {
            self.1 = None;
        }
    }
}

impl Launcher for LocalWorkers<'_> {
    type Worker = WorkProcess;

    fn spawn(
        &mut self,
        shard: u64,
        slot: usize,
        events: &Sender<(usize, Event)>,
    ) -> Result<WorkProcess> {
        let exe = std::env::current_exe().context("locating the sparc3d binary")?;
        let mut cmd = Command::new(exe);
        cmd.arg("work")
            .arg(&self.job_dir)
            .arg("--shard-index")
            .arg(shard.to_string())
            .arg("--events")
            .arg("--parent-pid")
            .arg(std::process::id().to_string())
            .arg("--control-stdin")
            .args(&self.limit_args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped());
        if std::env::var_os("RAYON_NUM_THREADS").is_none() {
            cmd.env("RAYON_NUM_THREADS", self.threads.to_string());
        }
        // A worker still running when `run` leaves (an error) is stopped as on Ctrl-C; the
        // worker itself asks to die with `run` (`--parent-pid`).
        let options = ProcessOptions {
            stderr_tail_bytes: STDERR_TAIL_BYTES,
            stop_signal: libc::SIGTERM,
            ..Default::default()
        };
        let mut process = Process::spawn(&mut cmd, &options)
            .with_context(|| format!("starting a worker for shard {shard}"))?;
        let control = process.take_stdin();
        if let Some(out) = process.take_stdout() {
            let tx = events.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(out).lines().map_while(Result::ok) {
                    if let Ok(e) = serde_json::from_str::<Event>(&line) {
                        if tx.send((slot, e)).is_err() {
                            return;
                        }
                    }
                }
            });
        }
        Ok(WorkProcess(process, control))
    }

    fn lease(&mut self, shard: u64) -> Option<LeaseInfo> {
        sparc3d_workers::lease::read(&self.job.layout.lease(shard))
    }

    fn shard_state(&mut self, shard: u64) -> Result<ShardState> {
        Ok(shard_state(
            &self.job.layout,
            shard,
            self.job.fingerprint(),
            Check::Quick,
        )?)
    }
}
