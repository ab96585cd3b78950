//! The one child-process supervisor: starts a child with its stderr captured into a bounded
//! tail, optionally tied to this process's life (parent-death signal) and in its own process
//! group; waits for it with a time limit and its resource use (`wait4`: CPU time, peak RSS);
//! stops it when its handle is dropped. Used by the item supervisor ([`crate::isolate::supervisor`]),
//! the `run` orchestrator's workers and `bench`'s subprocesses. The address-space limit of an
//! item worker is set by the child itself ([`set_memory_limit`]), after its start-up.

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::process::{Child, ChildStdin, ChildStdout, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How to start and stop a supervised child.
#[derive(Debug, Clone, Copy)]
pub struct ProcessOptions {
    /// Signal the child gets when the thread that started it dies (Linux `PR_SET_PDEATHSIG`,
    /// set between fork and exec); `None` for none.
    pub parent_death_signal: Option<i32>,
    /// Start the child in its own process group (a Ctrl-C at the terminal does not reach it).
    pub own_process_group: bool,
    /// Bytes of stderr kept (the end of it).
    pub stderr_tail_bytes: usize,
    /// Signal sent to a child still running when its handle is dropped (then it is reaped).
    pub stop_signal: i32,
}

impl Default for ProcessOptions {
    fn default() -> Self {
        Self {
            parent_death_signal: None,
            own_process_group: false,
            stderr_tail_bytes: 16 << 10,
            stop_signal: libc::SIGKILL,
        }
    }
}

/// The end of a child's stderr, read by a thread as it comes.
struct StderrTail {
    bytes: Arc<Mutex<Vec<u8>>>,
    /// Signalled when stderr reached its end.
    ended: Receiver<()>,
}

impl StderrTail {
    fn start(mut stderr: impl Read + Send + 'static, keep: usize) -> std::io::Result<Self> {
        let bytes = Arc::new(Mutex::new(Vec::new()));
        let (tx, ended) = mpsc::channel();
        let sink = bytes.clone();
        std::thread::Builder::new()
            .name("child-stderr".into())
            .spawn(move || {
                let mut buf = [0u8; 4096];
                while let Ok(n) = stderr.read(&mut buf) {
                    if n == 0 {
                        break;
                    }
                    if let Ok(mut g) = sink.lock() {
                        g.extend_from_slice(&buf[..n]);
                        let cut = g.len().saturating_sub(keep);
                        g.drain(..cut);
                    }
                }
                let _ = tx.send(());
            })?;
        Ok(Self { bytes, ended })
    }

    /// The last `max_bytes` read so far, from the first whole character.
    fn text(&self, max_bytes: usize) -> String {
        let bytes = self.bytes.lock().map(|g| g.clone()).unwrap_or_default();
        let mut start = bytes.len().saturating_sub(max_bytes);
        // Skip UTF-8 continuation bytes of a character cut by the tail's start.
        while start < bytes.len() && start > 0 && bytes[start] & 0xC0 == 0x80 {
            start += 1;
        }
        String::from_utf8_lossy(&bytes[start..]).into_owned()
    }
}

/// How a waited-for child ended, with its resource use.
#[derive(Debug, Clone, Copy)]
pub struct Usage {
    /// Raw wait status; `None` when the wait itself failed.
    pub status: Option<i32>,
    /// Whether it was killed for running past its time limit.
    pub timed_out: bool,
    /// User CPU seconds.
    pub user_seconds: f64,
    /// System CPU seconds.
    pub sys_seconds: f64,
    /// Peak resident set size (`ru_maxrss`), bytes.
    pub max_rss_bytes: Option<u64>,
}

impl Usage {
    /// Whether it exited by itself with status 0.
    pub fn success(&self) -> bool {
        self.status
            .is_some_and(|s| libc::WIFEXITED(s) && libc::WEXITSTATUS(s) == 0)
    }
}

/// A supervised child process.
pub struct Process {
    child: Child,
    tail: Option<StderrTail>,
    stop_signal: i32,
}

impl Process {
    /// Starts `cmd` with its stderr piped into the tail (stdin and stdout as `cmd` sets them).
    pub fn spawn(cmd: &mut Command, options: &ProcessOptions) -> std::io::Result<Self> {
        cmd.stderr(Stdio::piped());
        if options.own_process_group {
            cmd.process_group(0);
        }
        if let Some(signal) = options.parent_death_signal {
            set_parent_death_signal(cmd, signal);
        }
        let mut child = cmd.spawn()?;
        let tail = match child.stderr.take() {
            Some(err) => Some(StderrTail::start(err, options.stderr_tail_bytes)?),
            None => None,
        };
        Ok(Self {
            child,
            tail,
            stop_signal: options.stop_signal,
        })
    }

    /// Its process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Its stdin, if piped and not taken yet.
    pub fn take_stdin(&mut self) -> Option<ChildStdin> {
        self.child.stdin.take()
    }

    /// Its stdout, if piped and not taken yet.
    pub fn take_stdout(&mut self) -> Option<ChildStdout> {
        self.child.stdout.take()
    }

    /// Sends `signal` to it (unless it was reaped).
    pub fn signal(&self, signal: i32) {
        // SAFETY: sending a signal to a child we started; it is not reaped while we hold it
        // (a reaped child's pid is only signalled through `Drop`, which checks first).
        unsafe {
            libc::kill(self.child.id() as libc::pid_t, signal);
        }
    }

    /// Its exit status, if it has exited (reaping it).
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        self.child.try_wait().ok().flatten()
    }

    /// Kills it (SIGKILL), reaps it and waits until its stderr is read to the end.
    pub fn kill(&mut self) -> Option<ExitStatus> {
        let _ = self.child.kill();
        let status = self.child.wait().ok();
        self.wait_stderr_end(None);
        status
    }

    /// Waits (at most `limit`, `None` for no limit) until its stderr has been read to its end,
    /// so that the reason a child failed is never lost.
    pub fn wait_stderr_end(&self, limit: Option<Duration>) {
        if let Some(t) = &self.tail {
            let _ = match limit {
                Some(limit) => t.ended.recv_timeout(limit).ok(),
                None => t.ended.recv().ok(),
            };
        }
    }

    /// The last `max_bytes` of its stderr read so far.
    pub fn stderr_tail(&self, max_bytes: usize) -> String {
        self.tail
            .as_ref()
            .map(|t| t.text(max_bytes))
            .unwrap_or_default()
    }

    /// Forgets the stderr read so far (a new task starts in the same process).
    pub fn clear_stderr_tail(&self) {
        if let Some(Ok(mut g)) = self.tail.as_ref().map(|t| t.bytes.lock()) {
            g.clear();
        }
    }

    /// Waits for it with `wait4`, which reports the CPU time and peak RSS of this one process
    /// even when it was killed, killing it after `timeout`; then waits for its stderr's end.
    pub fn wait_with_usage(&mut self, timeout: Duration) -> Usage {
        let usage = wait4_with_timeout(&mut self.child, timeout);
        self.wait_stderr_end(None);
        usage
    }
}

impl Drop for Process {
    /// A child still running when its handle goes is stopped and reaped.
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            self.signal(self.stop_signal);
            let _ = self.child.wait();
        }
    }
}

/// Asks the kernel (between fork and exec) to send `signal` to the child when its parent
/// dies, so that it does not run on as an orphan.
fn set_parent_death_signal(cmd: &mut Command, signal: i32) {
    #[cfg(target_os = "linux")]
    // SAFETY: the closure only calls prctl, which is async-signal-safe, between fork and exec.
    unsafe {
        cmd.pre_exec(move || {
            libc::prctl(libc::PR_SET_PDEATHSIG, signal);
            Ok(())
        });
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (cmd, signal);
}

fn seconds(tv: libc::timeval) -> f64 {
    tv.tv_sec as f64 + tv.tv_usec as f64 * 1e-6
}

/// The `wait4` loop behind [`Process::wait_with_usage`].
fn wait4_with_timeout(child: &mut Child, timeout: Duration) -> Usage {
    let pid = child.id() as libc::pid_t;
    let start = Instant::now();
    let mut timed_out = false;
    let mut status: libc::c_int = 0;
    // SAFETY: rusage is plain old data; all-zero is a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let reaped = loop {
        let flags = if timed_out { 0 } else { libc::WNOHANG };
        // SAFETY: wait4 writes into the status and rusage we own; pid is our own child.
        let r = unsafe { libc::wait4(pid, &mut status, flags, &mut usage) };
        if r == pid {
            break true;
        }
        if r < 0 {
            if std::io::Error::last_os_error().kind() == std::io::ErrorKind::Interrupted {
                continue;
            }
            break false;
        }
        if !timed_out && start.elapsed() >= timeout {
            timed_out = true;
            let _ = child.kill();
            continue;
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Usage {
        status: reaped.then_some(status),
        timed_out,
        user_seconds: seconds(usage.ru_utime),
        sys_seconds: seconds(usage.ru_stime),
        max_rss_bytes: (reaped && usage.ru_maxrss > 0).then_some(usage.ru_maxrss as u64 * 1024),
    }
}

/// Limits this process's address space to `bytes` (`RLIMIT_AS`; 0: no limit), so that an
/// allocation past it fails instead of the machine swapping.
pub fn set_memory_limit(bytes: u64) -> std::io::Result<()> {
    if bytes == 0 {
        return Ok(());
    }
    let lim = libc::rlimit {
        rlim_cur: bytes as libc::rlim_t,
        rlim_max: bytes as libc::rlim_t,
    };
    // SAFETY: setrlimit reads a valid rlimit struct.
    if unsafe { libc::setrlimit(libc::RLIMIT_AS, &lim) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sh(script: &str) -> Command {
        let mut cmd = Command::new("sh");
        cmd.arg("-c").arg(script).stdin(Stdio::null());
        cmd
    }

    #[test]
    fn keeps_the_end_of_stderr_and_its_status() -> std::io::Result<()> {
        let options = ProcessOptions {
            stderr_tail_bytes: 8,
            ..Default::default()
        };
        let mut p = Process::spawn(&mut sh("printf 'first line\\nlast' >&2; exit 3"), &options)?;
        let usage = p.wait_with_usage(Duration::from_secs(30));
        assert!(!usage.timed_out && !usage.success());
        assert_eq!(usage.status.map(|s| libc::WEXITSTATUS(s)), Some(3));
        assert_eq!(p.stderr_tail(100), "ine\nlast");
        assert_eq!(p.stderr_tail(4), "last");
        p.clear_stderr_tail();
        assert_eq!(p.stderr_tail(100), "");
        Ok(())
    }

    #[test]
    fn a_cut_character_is_left_out_of_the_tail() -> std::io::Result<()> {
        let options = ProcessOptions {
            stderr_tail_bytes: 3,
            ..Default::default()
        };
        // "é" is two bytes: keeping three of "aé!" cuts nothing, keeping two cuts "é".
        let mut p = Process::spawn(&mut sh("printf 'a\\303\\251!' >&2"), &options)?;
        assert!(p.wait_with_usage(Duration::from_secs(30)).success());
        assert_eq!(p.stderr_tail(3), "é!");
        assert_eq!(p.stderr_tail(2), "!");
        Ok(())
    }

    #[test]
    fn a_child_past_its_time_limit_is_killed_with_its_usage() -> std::io::Result<()> {
        let mut p = Process::spawn(&mut sh("exec sleep 30"), &ProcessOptions::default())?;
        let start = Instant::now();
        let usage = p.wait_with_usage(Duration::from_millis(100));
        assert!(usage.timed_out);
        assert!(start.elapsed() < Duration::from_secs(20));
        let status = usage.status.unwrap_or(0);
        assert!(libc::WIFSIGNALED(status) && libc::WTERMSIG(status) == libc::SIGKILL);
        assert!(usage.max_rss_bytes.is_some_and(|b| b > 0));
        Ok(())
    }

    #[test]
    fn dropping_a_running_child_stops_it_with_its_signal() -> std::io::Result<()> {
        let options = ProcessOptions {
            stop_signal: libc::SIGTERM,
            ..Default::default()
        };
        let p = Process::spawn(&mut sh("exec sleep 30"), &options)?;
        let pid = p.id() as libc::pid_t;
        drop(p);
        // Reaped: the pid is no child of ours any more.
        // SAFETY: waitpid with WNOHANG on a pid; it only reports.
        let r = unsafe { libc::waitpid(pid, std::ptr::null_mut(), libc::WNOHANG) };
        assert_eq!(r, -1);
        Ok(())
    }

    #[test]
    fn a_child_dies_with_the_thread_that_started_it() -> std::io::Result<()> {
        let options = ProcessOptions {
            parent_death_signal: Some(libc::SIGKILL),
            ..Default::default()
        };
        // The starting thread ends at once; its child must not outlive it. The child's
        // pid comes back through the thread, and the handle is leaked so no drop reaps it.
        let pid = std::thread::spawn(move || -> std::io::Result<u32> {
            let p = Process::spawn(&mut sh("exec sleep 30"), &options)?;
            let pid = p.id();
            std::mem::forget(p);
            Ok(pid)
        })
        .join()
        .map_err(|_| std::io::Error::other("the starting thread panicked"))??;
        let mut status = 0;
        // SAFETY: waiting for our own child.
        let r = unsafe { libc::waitpid(pid as libc::pid_t, &mut status, 0) };
        assert_eq!(r, pid as libc::pid_t);
        assert!(libc::WIFSIGNALED(status) && libc::WTERMSIG(status) == libc::SIGKILL);
        Ok(())
    }
}
