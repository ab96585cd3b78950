//! `sparc3d run JOB [--workers N] [--item-timeout 10m] [--item-memory 8G]`: the local
//! orchestrator. Runs up to N `sparc3d work --events` processes, one shard each, shows
//! progress, and stops cleanly on Ctrl-C or SIGTERM; a later `run` resumes.
//! `sparc3d run DIR_OR_MANIFEST --job OUT` first makes the job OUT (as `manifest build` and
//! `init` would) when it does not exist yet, and resumes it when it does.
//!
//! Its workers die with it (they stop as on SIGTERM when `run` is killed, releasing their
//! leases). A shard leased by another live worker (another `run`, a cluster task, or the
//! workers of a `run` just killed) is waited for and taken over once its lease is released
//! or expires; one shard's failure does not stop the others; and `run` exits 0 only when every
//! shard is done, otherwise it names what is left and exits non-zero.

use super::work::LimitArgs;
use crate::progress::Progress;
use crate::signals::install_signals;
use crate::summary::{shard_states, summarize, summarize_states};
use crate::units::{format_seconds, parse_duration};
use anyhow::{Context, Result};
use sparc3d_workers::events::Event;
use sparc3d_workers::store::state::{shard_state, Check, ShardState};
use sparc3d_workers::Job;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Arguments of `sparc3d run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A job folder; or, with --job, a folder of meshes or a manifest to make the job from.
    #[arg(value_name = "JOB|DIR|MANIFEST")]
    pub input: PathBuf,
    /// The job folder to run: made from INPUT (a folder of meshes, scanned as `manifest build`
    /// does, or a manifest) with the config flags when it is not a job yet, resumed when it is.
    #[arg(long, value_name = "OUT")]
    pub job: Option<PathBuf>,
    #[command(flatten)]
    pub config: super::init::ConfigArgs,
    /// Worker processes (default: number of cores).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Seconds between progress lines when not on a terminal.
    #[arg(long, default_value = "10s", value_parser = parse_duration)]
    pub log_interval: f64,
    #[command(flatten)]
    pub limits: LimitArgs,
    /// When every shard is done, check this sample of the ok items with pymeshlab (`1%` or a
    /// count), as `sparc3d validate JOB --sample SAMPLE` does.
    #[arg(long, value_name = "SAMPLE")]
    pub validate_sample: Option<crate::sample::SampleSize>,
}

/// Times a shard's worker may be killed by a signal before the run gives up on it.
const MAX_WORKER_DEATHS: u32 = 20;

/// Times a shard's worker may end without finishing it (its lease was held elsewhere) before
/// the run gives up on it.
const MAX_UNFINISHED_EXITS: u32 = 1000;

/// How often shards leased by other workers are looked at again.
const WAIT_POLL: Duration = Duration::from_millis(250);

/// A `work` process and the shard it runs.
struct Running {
    child: Child,
    shard: u64,
    stderr: Arc<Mutex<String>>,
    /// Signalled when its stderr reached its end.
    stderr_done: mpsc::Receiver<()>,
}

impl Running {
    /// The end of its stderr, once the process has exited: waits (briefly) until the reader
    /// has read everything, so that the reason a worker failed is never lost.
    fn stderr_tail(&self) -> String {
        let _ = self.stderr_done.recv_timeout(Duration::from_secs(5));
        self.stderr
            .lock()
            .map(|g| g.trim().to_string())
            .unwrap_or_default()
    }
}

impl Drop for Running {
    /// A worker still running when `run` leaves (an error) is stopped and reaped.
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            // SAFETY: sending SIGTERM to a child we started and have not reaped.
            unsafe {
                libc::kill(self.child.id() as libc::pid_t, libc::SIGTERM);
            }
            let _ = self.child.wait();
        }
    }
}

fn spawn_work(
    job: &Path,
    args: &Args,
    shard: u64,
    slot: usize,
    threads: usize,
    tx: &mpsc::Sender<(usize, Event)>,
) -> Result<Running> {
    let exe = std::env::current_exe().context("locating the sparc3d binary")?;
    let mut cmd = Command::new(exe);
    cmd.arg("work")
        .arg(job)
        .arg("--shard-index")
        .arg(shard.to_string())
        .arg("--events")
        .arg("--parent-pid")
        .arg(std::process::id().to_string())
        .args(args.limits.to_args())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        cmd.env("RAYON_NUM_THREADS", threads.to_string());
    }
    let mut child = cmd
        .spawn()
        .with_context(|| format!("starting a worker for shard {shard}"))?;
    let stderr = Arc::new(Mutex::new(String::new()));
    let (done_tx, stderr_done) = mpsc::channel();
    if let Some(out) = child.stdout.take() {
        let tx = tx.clone();
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
    if let Some(mut err) = child.stderr.take() {
        let tail = stderr.clone();
        std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                if let Ok(mut g) = tail.lock() {
                    g.push_str(&String::from_utf8_lossy(&buf[..n]));
                    if g.len() > 8192 {
                        let cut = g.len() - 8192;
                        let cut = (cut..g.len()).find(|&i| g.is_char_boundary(i)).unwrap_or(0);
                        g.drain(..cut);
                    }
                }
            }
            let _ = done_tx.send(());
        });
    }
    Ok(Running {
        child,
        shard,
        stderr,
        stderr_done,
    })
}

/// The shards this run must still see finished: those to start now, and those leased by
/// another live worker (to wait for), from the shards' states.
fn plan(states: &[ShardState], progress: &Progress) -> (VecDeque<u64>, BTreeMap<u64, String>) {
    let mut queue = VecDeque::new();
    let mut waiting = BTreeMap::new();
    for (shard, state) in (0..).zip(states) {
        match state {
            ShardState::Done(_) => {}
            ShardState::Running(l) => {
                progress.println(&format!(
                    "shard {shard}: leased by {}; waiting for it to finish or its lease to expire",
                    l.owner
                ));
                waiting.insert(shard, l.owner.clone());
            }
            ShardState::Damaged(why) => {
                progress.println(&format!(
                    "shard {shard}: damaged ({why}); converting it again"
                ));
                queue.push_back(shard);
            }
            ShardState::Pending => queue.push_back(shard),
        }
    }
    (queue, waiting)
}

/// Runs `sparc3d run`.
pub fn run(args: Args) -> Result<ExitCode> {
    let job_dir = crate::job_setup::job_for_run(&args.input, args.job.as_deref(), &args.config)?;
    let job = Job::open(&job_dir)?;
    let stop = install_signals()?;
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let workers = args.workers.unwrap_or(cores).max(1);
    let threads = (cores / workers).max(1);
    let start = Instant::now();
    let states = shard_states(&job, Check::Quick)?;
    let before = summarize_states(&job, &states);
    let mut progress = Progress::new(
        job.file.items,
        before.ok,
        before.failed,
        workers,
        args.log_interval,
    );
    let (mut queue, mut waiting) = plan(&states, &progress);
    progress.println(&format!(
        "{}: {} items, {} shards left, {workers} workers",
        job_dir.display(),
        before.pending,
        queue.len() + waiting.len()
    ));
    let (tx, rx) = mpsc::channel::<(usize, Event)>();
    let mut slots: Vec<Option<Running>> = (0..workers).map(|_| None).collect();
    // Workers whose items are all done and that are writing their shard: their slot already
    // runs the next shard, so writing overlaps converting.
    let mut writing: Vec<Running> = Vec::new();
    let mut errors: Vec<String> = Vec::new();
    let mut signalled = false;
    let mut killed: HashMap<u64, u32> = HashMap::new();
    let mut unfinished: HashMap<u64, u32> = HashMap::new();
    let mut last_look = Instant::now();
    loop {
        let stopping = stop.requested();
        if !stopping {
            for (slot, s) in slots.iter_mut().enumerate() {
                if s.is_none() {
                    let Some(shard) = queue.pop_front() else {
                        break;
                    };
                    *s = Some(spawn_work(&job_dir, &args, shard, slot, threads, &tx)?);
                    progress.slot_shard(slot, Some(shard));
                }
            }
        }
        if stopping && !signalled {
            signalled = true;
            for r in slots.iter().flatten() {
                // SAFETY: sending SIGTERM to a child we started.
                unsafe {
                    libc::kill(r.child.id() as libc::pid_t, libc::SIGTERM);
                }
            }
        }
        // Shards held elsewhere: finished there, or free to take over.
        if !stopping && !waiting.is_empty() && last_look.elapsed() >= WAIT_POLL {
            last_look = Instant::now();
            let mut free = Vec::new();
            for &shard in waiting.keys() {
                match shard_state(&job.layout, shard, job.fingerprint(), Check::Quick)? {
                    ShardState::Running(_) => {}
                    ShardState::Done(_) => free.push((shard, false)),
                    ShardState::Pending | ShardState::Damaged(_) => free.push((shard, true)),
                }
            }
            for (shard, todo) in free {
                waiting.remove(&shard);
                if todo {
                    queue.push_back(shard);
                }
            }
        }
        if slots.iter().all(Option::is_none)
            && writing.is_empty()
            && ((queue.is_empty() && waiting.is_empty()) || stopping)
        {
            break;
        }
        let mut next = rx.recv_timeout(Duration::from_millis(20)).ok();
        while let Some((slot, e)) = next {
            match e {
                Event::ItemStarted { uri, .. } => progress.item_started(slot, &uri),
                Event::ItemFinished { status, .. } => progress.item_finished(slot, &status),
                Event::ShardSkipped { shard, reason } => {
                    progress.println(&format!("shard {shard}: {reason}"))
                }
                Event::ShardDamaged {
                    shard,
                    reason,
                    moved_to,
                } => progress.println(&format!(
                    "shard {shard}: damaged ({reason}); moved aside to {moved_to}, converting it \
                     again"
                )),
                Event::ShardWriting { shard } => {
                    if let Some(r) = slots[slot].take_if(|r| r.shard == shard) {
                        writing.push(r);
                        progress.slot_shard(slot, None);
                    }
                }
                _ => {}
            }
            next = rx.try_recv().ok();
        }
        // Writers that exited, then slot workers that exited.
        let mut exited: Vec<(Option<usize>, Running, std::process::ExitStatus)> = Vec::new();
        let mut i = 0;
        while i < writing.len() {
            match writing[i].child.try_wait() {
                Ok(Some(status)) => exited.push((None, writing.swap_remove(i), status)),
                _ => i += 1,
            }
        }
        for (slot, s) in slots.iter_mut().enumerate() {
            if let Some(status) = s.as_mut().and_then(|r| r.child.try_wait().ok().flatten()) {
                if let Some(r) = s.take() {
                    exited.push((Some(slot), r, status));
                }
            }
        }
        for (slot, r, status) in exited {
            if let Some(slot) = slot {
                progress.slot_shard(slot, None);
            }
            if stop.requested() {
                continue;
            }
            if status.success() {
                // Done, or held by another worker (it said "leased by"): wait for that one.
                match shard_state(&job.layout, r.shard, job.fingerprint(), Check::Quick)? {
                    ShardState::Done(_) => {}
                    other => {
                        let n = unfinished.entry(r.shard).or_insert(0);
                        *n += 1;
                        if *n > MAX_UNFINISHED_EXITS {
                            let msg = format!(
                                "shard {} is still not finished after {n} tries ({other:?})",
                                r.shard
                            );
                            progress.println(&msg);
                            errors.push(msg);
                        } else {
                            let holder = match other {
                                ShardState::Running(l) => l.owner,
                                _ => "another worker".into(),
                            };
                            waiting.insert(r.shard, holder);
                        }
                    }
                }
                continue;
            }
            let deaths = killed.entry(r.shard).or_insert(0);
            if status.signal().is_some() && *deaths < MAX_WORKER_DEATHS {
                // Killed from outside (kill -9, OOM killer): the journal keeps its finished
                // items; a new worker takes the shard over.
                *deaths += 1;
                progress.println(&format!(
                    "shard {}: worker {status}; restarting it",
                    r.shard
                ));
                queue.push_back(r.shard);
                continue;
            }
            let tail = r.stderr_tail();
            let reason = if tail.is_empty() {
                "the worker printed no error".to_string()
            } else {
                tail
            };
            // This shard is left for a later run; the others go on.
            let msg = format!("shard {} failed ({status}): {reason}", r.shard);
            progress.println(&msg);
            errors.push(msg);
        }
        progress.tick();
    }
    // Drain the last events.
    while let Ok((slot, e)) = rx.try_recv() {
        if let Event::ItemFinished { status, .. } = e {
            progress.item_finished(slot, &status);
        }
    }
    let (ok, failed, retried) = progress.finish();
    let elapsed = start.elapsed().as_secs_f64();
    let after = summarize(&job)?;
    let converted = (after.ok + after.failed).saturating_sub(before.ok + before.failed);
    eprintln!(
        "{converted} items in {} ({ok} ok, {failed} failed in total, {retried} crash retries); \
         {} of {} shards done; item time {:.1}s over {:.1}s wall on {workers} workers",
        format_seconds(elapsed),
        after.shards_done,
        after.shards,
        after.item_seconds - before.item_seconds,
        elapsed,
    );
    // The last line points to the failures, whatever the outcome.
    let failures_hint = || {
        if let Some(hint) = crate::hints::failures(&job_dir, after.failed) {
            eprintln!("{hint}");
        }
    };
    if stop.requested() {
        eprintln!("stopped; `sparc3d run {}` resumes", job_dir.display());
        failures_hint();
        return Ok(stop.exit_code());
    }
    if after.shards_done < after.shards || after.pending > 0 {
        let left: Vec<String> = shard_states(&job, Check::Quick)?
            .iter()
            .enumerate()
            .filter(|(_, s)| !matches!(s, ShardState::Done(_)))
            .map(|(i, _)| i.to_string())
            .take(20)
            .collect();
        eprintln!(
            "error: {} items in {} shards are not finished (shards {}{}); {}fix the cause and \
             run again to resume (finished items are kept)",
            after.pending,
            after.shards - after.shards_done,
            left.join(", "),
            if after.shards - after.shards_done > 20 {
                ", …"
            } else {
                ""
            },
            if errors.is_empty() {
                String::new()
            } else {
                format!("{} shard(s) failed (above); ", errors.len())
            },
        );
        failures_hint();
        return Ok(ExitCode::FAILURE);
    }
    eprintln!("{}", crate::hints::next_steps(&job_dir, after.shards));
    failures_hint();
    if let Some(sample) = args.validate_sample {
        return super::validate::after_run(&job_dir, sample);
    }
    Ok(ExitCode::SUCCESS)
}
