//! Runs items in an item worker process ([`crate::isolate::child`]) with a watchdog: a time-out kills
//! the process, and any death of the process (signal, abort, allocation failure, stack
//! overflow) is classified and attributed to the item it was converting. A dead process is
//! replaced at the next item.

use crate::error::{Result, WorkerError};
use crate::isolate::process::{Process, ProcessOptions};
use crate::journal::record::{self, ReadFrame, Record};
use sparc3d_schema::{ErrorClass, FrozenItem, JobConfig, Limits, ShardRow};
use std::io::{BufReader, Write};
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// Bytes of stderr kept per item.
const TAIL_BYTES: usize = 16 << 10;
/// Bytes of stderr stored in a failed row.
const ROW_TAIL_BYTES: usize = 2 << 10;

/// How to start an item worker process: a program and its arguments (the supervisor adds
/// `--memory-bytes B --parent-pid P`).
#[derive(Debug, Clone)]
pub struct ChildCommand {
    /// The program (usually the running `sparc3d` binary).
    pub program: PathBuf,
    /// Arguments selecting the item worker mode.
    pub args: Vec<String>,
    /// Extra environment variables.
    pub env: Vec<(String, String)>,
}

/// How an item ended.
#[derive(Debug)]
pub enum ItemOutcome {
    /// The worker answered with a row (ok or failed).
    Finished(Box<ShardRow>),
    /// The worker process died or was killed by the watchdog.
    Died {
        /// Class of the death.
        class: ErrorClass,
        /// What happened.
        message: String,
        /// The last lines of its stderr.
        stderr_tail: String,
    },
    /// Stopped on request (Ctrl-C); not the item's fault.
    Stopped,
}

enum Msg {
    Row(Box<ShardRow>),
    Closed,
}

struct ChildProc {
    process: Process,
    stdin: ChildStdin,
    rx: Receiver<Msg>,
}

impl ChildProc {
    fn kill(&mut self) -> Option<ExitStatus> {
        self.process.kill()
    }

    fn tail(&self) -> String {
        self.process.stderr_tail(ROW_TAIL_BYTES)
    }
}

/// Runs items one at a time in a supervised item worker process.
pub struct ItemRunner {
    cmd: ChildCommand,
    config_line: String,
    limits: Limits,
    proc: Option<ChildProc>,
    /// Threads of the item worker's conversions (`RAYON_NUM_THREADS`; 0: the environment's).
    threads: usize,
}

fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGKILL => "SIGKILL",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGTERM => "SIGTERM",
        libc::SIGINT => "SIGINT",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        _ => "signal",
    }
}

/// A memory limit in the units `--item-memory` takes (powers of 1024): `8G`, `20M`, `1.5G`,
/// or `none` for 0.
pub fn describe_memory_limit(bytes: u64) -> String {
    let (unit, size) = match bytes {
        0 => return "none".into(),
        b if b >= 1 << 30 => ("G", b as f64 / (1u64 << 30) as f64),
        b => ("M", b as f64 / (1u64 << 20) as f64),
    };
    let text = format!("{size:.1}");
    format!("{}{unit}", text.strip_suffix(".0").unwrap_or(&text))
}

/// Classifies the death of an item worker from its exit status and stderr; `memory_bytes` is
/// the item memory limit it ran under. The message says what happened without repeating the
/// class's name.
pub fn classify_death(
    status: Option<ExitStatus>,
    stderr: &str,
    memory_bytes: u64,
) -> (ErrorClass, String) {
    let how = match status {
        Some(s) => match (s.signal(), s.code()) {
            (Some(sig), _) => format!("killed by signal {sig} ({})", signal_name(sig)),
            (None, Some(code)) => format!("exited with status {code}"),
            _ => "ended".to_string(),
        },
        None => "vanished".to_string(),
    };
    if stderr.contains("has overflowed its stack") {
        (
            ErrorClass::StackOverflow,
            format!("item worker {how} after its conversion thread ran past its stack"),
        )
    } else if stderr.contains("memory allocation of")
        || stderr.contains("Cannot allocate memory")
        || stderr.contains("out of memory")
    {
        (
            ErrorClass::OutOfMemory,
            format!(
                "item worker {how}: an allocation failed under the item memory limit of {} \
                 (--item-memory)",
                describe_memory_limit(memory_bytes)
            ),
        )
    } else {
        (ErrorClass::Crashed, format!("item worker {how}"))
    }
}

impl ItemRunner {
    /// A runner for a job's config and limits; the process starts with the first item.
    pub fn new(cmd: ChildCommand, config: &JobConfig, limits: Limits) -> Result<Self> {
        let config_line = serde_json::to_string(config)
            .map_err(|e| WorkerError::Child(format!("encoding the config: {e}")))?;
        Ok(Self {
            cmd,
            config_line,
            limits,
            proc: None,
            threads: 0,
        })
    }

    /// Converts the next items with `threads` threads (0: as the environment says): an idle
    /// item worker started with another count is replaced at the next item. The output does
    /// not depend on it.
    pub fn set_threads(&mut self, threads: usize) {
        if threads != self.threads {
            self.threads = threads;
            if let Some(mut p) = self.proc.take() {
                p.kill();
            }
        }
    }

    fn spawn(&self) -> Result<ChildProc> {
        let mut cmd = Command::new(&self.cmd.program);
        cmd.args(&self.cmd.args)
            .arg("--memory-bytes")
            .arg(self.limits.item_memory_bytes.to_string())
            .arg("--parent-pid")
            .arg(std::process::id().to_string())
            .envs(self.cmd.env.iter().map(|(k, v)| (k, v)))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped());
        if self.threads > 0 {
            cmd.env("RAYON_NUM_THREADS", self.threads.to_string());
        }
        let options = ProcessOptions {
            own_process_group: true,
            stderr_tail_bytes: TAIL_BYTES,
            ..Default::default()
        };
        let mut process = Process::spawn(&mut cmd, &options).map_err(|e| {
            WorkerError::Child(format!(
                "starting {}: {e}{}",
                self.cmd.program.display(),
                crate::error::hint(&e)
            ))
        })?;
        let (Some(mut stdin), Some(stdout)) = (process.take_stdin(), process.take_stdout()) else {
            return Err(WorkerError::Child("no pipes to the item worker".into()));
        };
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::Builder::new()
            .name("item-reader".into())
            .spawn(move || {
                let mut r = BufReader::new(stdout);
                loop {
                    match record::read(&mut r) {
                        Ok(ReadFrame::Record(Record::Done { row, .. }, _)) => {
                            if tx.send(Msg::Row(row)).is_err() {
                                return;
                            }
                        }
                        Ok(_) | Err(_) => {
                            let _ = tx.send(Msg::Closed);
                            return;
                        }
                    }
                }
            })
            .map_err(|e| WorkerError::Child(format!("starting a reader thread: {e}")))?;
        writeln!(stdin, "{}", self.config_line)
            .map_err(|e| WorkerError::Child(format!("sending the config: {e}")))?;
        Ok(ChildProc { process, stdin, rx })
    }

    fn died(&mut self, mut proc: ChildProc, timeout: bool) -> ItemOutcome {
        let status = proc.kill();
        let tail = proc.tail();
        if timeout {
            return ItemOutcome::Died {
                class: ErrorClass::Timeout,
                message: format!(
                    "exceeded the item time limit of {} s",
                    self.limits.item_timeout_s
                ),
                stderr_tail: tail,
            };
        }
        let (class, message) = classify_death(status, &tail, self.limits.item_memory_bytes);
        ItemOutcome::Died {
            class,
            message,
            stderr_tail: tail,
        }
    }

    /// Runs one item; `stop` is polled so that Ctrl-C (or a lost lease) interrupts a long
    /// item.
    pub fn run(&mut self, item: &FrozenItem, stop: &dyn Fn() -> bool) -> Result<ItemOutcome> {
        let mut proc = match self.proc.take() {
            Some(p) => p,
            None => self.spawn()?,
        };
        proc.process.clear_stderr_tail();
        let line = serde_json::to_string(item)
            .map_err(|e| WorkerError::Child(format!("encoding item {}: {e}", item.index)))?;
        if writeln!(proc.stdin, "{line}")
            .and_then(|_| proc.stdin.flush())
            .is_err()
        {
            return Ok(self.died(proc, false));
        }
        let start = Instant::now();
        let limit = Duration::from_secs_f64(self.limits.item_timeout_s.max(0.001));
        loop {
            match proc.rx.recv_timeout(Duration::from_millis(50)) {
                Ok(Msg::Row(mut row)) => {
                    if row.error_class.is_some() {
                        let tail = proc.tail();
                        if !tail.is_empty() {
                            row.stderr_tail = Some(tail);
                        }
                    }
                    self.proc = Some(proc);
                    return Ok(ItemOutcome::Finished(row));
                }
                Ok(Msg::Closed) | Err(RecvTimeoutError::Disconnected) => {
                    return Ok(self.died(proc, false));
                }
                Err(RecvTimeoutError::Timeout) => {
                    if stop() {
                        proc.kill();
                        return Ok(ItemOutcome::Stopped);
                    }
                    if start.elapsed() > limit {
                        return Ok(self.died(proc, true));
                    }
                }
            }
        }
    }
}

impl Drop for ItemRunner {
    fn drop(&mut self) {
        if let Some(mut p) = self.proc.take() {
            p.kill();
        }
    }
}
