//! Stopping cleanly on SIGINT and SIGTERM: the flag the work loops poll, and which signal
//! came (`work` and `run` exit with 128 + its number).

use anyhow::{Context, Result};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// A stop requested by SIGINT or SIGTERM: the flag the work loops poll, and which signal
/// came (for the exit status).
#[derive(Debug, Clone)]
pub struct Stop {
    /// Set by either signal.
    pub flag: Arc<AtomicBool>,
    signal: Arc<AtomicUsize>,
}

impl Stop {
    /// Whether a stop was requested.
    pub fn requested(&self) -> bool {
        self.flag.load(Ordering::SeqCst)
    }

    /// The signal that requested the stop (SIGTERM when none is recorded).
    pub fn signal(&self) -> i32 {
        match self.signal.load(Ordering::SeqCst) {
            0 => libc::SIGTERM,
            s => s as i32,
        }
    }

    /// The conventional exit status of a process stopped by that signal: 128 + its number
    /// (130 for SIGINT, 143 for SIGTERM).
    pub fn exit_code(&self) -> ExitCode {
        ExitCode::from((128 + self.signal()).clamp(0, 255) as u8)
    }
}

/// SIGINT/SIGTERM request a stop ([`Stop`]); SIGXFSZ is ignored so that a file-size limit
/// makes writes fail with an error instead of killing the process, and SIGPIPE so that a
/// write to a child that has just exited (a worker's share, an item worker's next item) fails
/// with an error its caller handles instead of killing `run` or `work`.
pub fn install_signals() -> Result<Stop> {
    let stop = Stop {
        flag: Arc::new(AtomicBool::new(false)),
        signal: Arc::new(AtomicUsize::new(0)),
    };
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register_usize(sig, stop.signal.clone(), sig as usize)
            .context("installing signal handlers")?;
        signal_hook::flag::register(sig, stop.flag.clone())
            .context("installing signal handlers")?;
    }
    // SAFETY: setting a signal's disposition to SIG_IGN has no preconditions.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
    Ok(stop)
}
