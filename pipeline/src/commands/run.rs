//! `sparc3d run JOB [--workers N] [--item-timeout 10m] [--item-memory 8G]`: the local
//! orchestrator. Runs up to N `sparc3d work --events` processes, one shard each, shows
//! progress, and stops cleanly on Ctrl-C; a later `run` resumes.

use super::work::{install_signals, LimitArgs};
use crate::progress::Progress;
use crate::summary::summarize;
use crate::units::{format_seconds, parse_duration};
use anyhow::{Context, Result};
use sparc3d_workers::events::Event;
use sparc3d_workers::state::{shard_state, ShardState};
use sparc3d_workers::Job;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read};
use std::os::unix::process::ExitStatusExt;
use std::path::PathBuf;
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Arguments of `sparc3d run`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder.
    pub job: PathBuf,
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

struct Running {
    child: Child,
    shard: u64,
    stderr: Arc<Mutex<String>>,
}

fn spawn_work(
    args: &Args,
    shard: u64,
    slot: usize,
    threads: usize,
    tx: &mpsc::Sender<(usize, Event)>,
) -> Result<Running> {
    let exe = std::env::current_exe().context("locating the sparc3d binary")?;
    let mut cmd = Command::new(exe);
    cmd.arg("work")
        .arg(&args.job)
        .arg("--shard-index")
        .arg(shard.to_string())
        .arg("--events")
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
        });
    }
    Ok(Running {
        child,
        shard,
        stderr,
    })
}

/// Runs `sparc3d run`.
pub fn run(args: Args) -> Result<ExitCode> {
    let job = Job::open(&args.job)?;
    let stop = install_signals()?;
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    let workers = args.workers.unwrap_or(cores).max(1);
    let threads = (cores / workers).max(1);
    let start = Instant::now();
    let before = summarize(&job)?;
    let mut queue: VecDeque<u64> = VecDeque::new();
    for shard in 0..job.file.shards {
        if !matches!(
            shard_state(&job.layout, shard, job.fingerprint())?,
            ShardState::Done(_)
        ) {
            queue.push_back(shard);
        }
    }
    let mut progress = Progress::new(
        job.file.items,
        before.ok,
        before.failed,
        workers,
        args.log_interval,
    );
    progress.println(&format!(
        "{}: {} items, {} shards left, {workers} workers",
        args.job.display(),
        before.pending,
        queue.len()
    ));
    let (tx, rx) = mpsc::channel::<(usize, Event)>();
    let mut slots: Vec<Option<Running>> = (0..workers).map(|_| None).collect();
    // Workers whose items are all done and that are writing their shard: their slot already
    // runs the next shard, so writing overlaps converting.
    let mut writing: Vec<Running> = Vec::new();
    let mut errors: Vec<String> = Vec::new();
    let mut signalled = false;
    let mut killed: std::collections::HashMap<u64, u32> = std::collections::HashMap::new();
    loop {
        let stopping = stop.load(Ordering::SeqCst);
        if !stopping && errors.is_empty() {
            for (slot, s) in slots.iter_mut().enumerate() {
                if s.is_none() {
                    let Some(shard) = queue.pop_front() else {
                        break;
                    };
                    *s = Some(spawn_work(&args, shard, slot, threads, &tx)?);
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
        if slots.iter().all(Option::is_none)
            && writing.is_empty()
            && (queue.is_empty() || stopping || !errors.is_empty())
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
            if !status.success() && !stop.load(Ordering::SeqCst) {
                let tail = r
                    .stderr
                    .lock()
                    .map(|g| g.trim().to_string())
                    .unwrap_or_default();
                let deaths = killed.entry(r.shard).or_insert(0);
                if status.signal().is_some() && *deaths < MAX_WORKER_DEATHS {
                    // Killed from outside (kill -9, OOM killer): the journal keeps its
                    // finished items; a new worker takes the shard over.
                    *deaths += 1;
                    progress.println(&format!(
                        "shard {}: worker {status}; restarting it",
                        r.shard
                    ));
                    queue.push_back(r.shard);
                } else {
                    let msg = format!("shard {} failed ({status}): {tail}", r.shard);
                    progress.println(&msg);
                    errors.push(msg);
                }
            }
            if let Some(slot) = slot {
                progress.slot_shard(slot, None);
            }
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
    if stop.load(Ordering::SeqCst) {
        eprintln!("stopped; `sparc3d run {}` resumes", args.job.display());
        return Ok(ExitCode::from(130));
    }
    if !errors.is_empty() {
        eprintln!(
            "error: {} shard(s) could not be finished; fix the cause and run again to resume \
             (finished items are kept)",
            errors.len()
        );
        return Ok(ExitCode::FAILURE);
    }
    if let Some(sample) = args.validate_sample {
        return super::validate::after_run(&args.job, sample);
    }
    Ok(ExitCode::SUCCESS)
}
