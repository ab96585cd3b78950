//! Progress display of `run`: indicatif bars on a terminal (items done/failed, rate, ETA, one
//! line per worker), plain periodic log lines otherwise.

use crate::rows::summary::rate_per_hour;
use crate::util::units::format_seconds;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// What a worker slot is doing.
#[derive(Debug, Clone, Default)]
struct Slot {
    shard: Option<u64>,
    /// The item it started last, and when.
    item: Option<(String, Instant)>,
    /// Items it converts now (more than one with several lanes).
    busy: usize,
}

/// What a run's workers did, as their events said.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Items ok in the job (before and during this run).
    pub ok: u64,
    /// Items failed in the job.
    pub failed: u64,
    /// Crashes retried in this run.
    pub retried: u64,
    /// The most items converting at once in this run.
    pub most_at_once: usize,
}

/// Counters and display of a local run.
pub struct Progress {
    bars: Option<(MultiProgress, ProgressBar, Vec<ProgressBar>)>,
    slots: Vec<Slot>,
    total: u64,
    ok: u64,
    failed: u64,
    retried: u64,
    done_this_run: u64,
    /// Items converting now, over all workers, and the most at once.
    at_once: usize,
    most_at_once: usize,
    start: Instant,
    interval: Duration,
    last_log: Instant,
}

impl Progress {
    /// A display for `total` items of which `ok` and `failed` are already done.
    pub fn new(total: u64, ok: u64, failed: u64, workers: usize, log_interval_s: f64) -> Self {
        let bars = std::io::stderr().is_terminal().then(|| {
            let mp = MultiProgress::with_draw_target(ProgressDrawTarget::stderr());
            let style = ProgressStyle::with_template(
                "{bar:30.cyan/blue} {pos}/{len} items {msg} [{elapsed_precise}]",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar());
            let main = mp.add(ProgressBar::new(total).with_style(style));
            main.set_position(ok + failed);
            main.reset_eta();
            let lines = (0..workers)
                .map(|_| {
                    let b = mp.add(ProgressBar::new_spinner());
                    b.set_style(
                        ProgressStyle::with_template("  {msg}")
                            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
                    );
                    b
                })
                .collect();
            (mp, main, lines)
        });
        let now = Instant::now();
        Self {
            bars,
            slots: vec![Slot::default(); workers],
            total,
            ok,
            failed,
            retried: 0,
            done_this_run: 0,
            at_once: 0,
            most_at_once: 0,
            start: now,
            interval: Duration::from_secs_f64(log_interval_s.max(0.1)),
            last_log: now,
        }
    }

    /// Prints a line above the bars (or to stderr).
    pub fn println(&self, line: &str) {
        match &self.bars {
            Some((mp, _, _)) => {
                let _ = mp.println(line);
            }
            None => eprintln!("{line}"),
        }
    }

    /// A worker slot took a shard (or became idle with `None`).
    pub fn slot_shard(&mut self, slot: usize, shard: Option<u64>) {
        if let Some(s) = self.slots.get_mut(slot) {
            self.at_once = self.at_once.saturating_sub(s.busy);
            *s = Slot {
                shard,
                ..Slot::default()
            };
        }
    }

    /// A worker slot started an item.
    pub fn item_started(&mut self, slot: usize, uri: &str) {
        if let Some(s) = self.slots.get_mut(slot) {
            s.item = Some((uri.to_string(), Instant::now()));
            s.busy += 1;
            self.at_once += 1;
            self.most_at_once = self.most_at_once.max(self.at_once);
        }
    }

    /// A worker slot finished an item with `status` (`ok`, `failed`, `retry`).
    pub fn item_finished(&mut self, slot: usize, status: &str) {
        match status {
            "ok" => self.ok += 1,
            "retry" => self.retried += 1,
            _ => self.failed += 1,
        }
        if status != "retry" {
            self.done_this_run += 1;
        }
        if let Some(s) = self.slots.get_mut(slot) {
            if s.busy > 0 {
                s.busy -= 1;
                self.at_once = self.at_once.saturating_sub(1);
            }
            if s.busy == 0 {
                s.item = None;
            }
        }
    }

    /// Items per hour in this run, once enough items finished ([`rate_per_hour`]).
    fn rate_per_hour(&self) -> Option<f64> {
        rate_per_hour(self.done_this_run, self.start.elapsed().as_secs_f64())
    }

    /// "1234/h, ETA 5m02s", or "rate not known yet" while too few items have finished.
    fn rate_text(&self) -> String {
        let remaining = self.total.saturating_sub(self.ok + self.failed) as f64;
        match self.rate_per_hour() {
            Some(rate) => format!(
                "{rate:.0}/h, ETA {}",
                format_seconds(remaining / rate * 3600.0)
            ),
            None => "rate not known yet".into(),
        }
    }

    fn slot_text(&self, i: usize) -> String {
        let s = &self.slots[i];
        match (&s.shard, &s.item) {
            (Some(sh), Some((uri, t))) => format!(
                "w{i}: shard {sh} {} ({}){}",
                uri.rsplit('/').next().unwrap_or(uri),
                format_seconds(t.elapsed().as_secs_f64()),
                match s.busy {
                    0 | 1 => String::new(),
                    n => format!(" and {} more", n - 1),
                }
            ),
            (Some(sh), None) => format!("w{i}: shard {sh}"),
            _ => format!("w{i}: idle"),
        }
    }

    /// Refreshes the display; on a non-terminal, logs a line every interval.
    pub fn tick(&mut self) {
        let done = self.ok + self.failed;
        let msg = format!(
            "({} ok, {} failed, {} retried) {}",
            self.ok,
            self.failed,
            self.retried,
            self.rate_text()
        );
        if let Some((_, main, lines)) = &self.bars {
            main.set_position(done);
            main.set_message(msg);
            for (i, l) in lines.iter().enumerate() {
                l.set_message(self.slot_text(i));
            }
            return;
        }
        if self.last_log.elapsed() < self.interval {
            return;
        }
        self.last_log = Instant::now();
        let busy: Vec<String> = (0..self.slots.len())
            .filter(|&i| self.slots[i].shard.is_some())
            .map(|i| self.slot_text(i))
            .collect();
        eprintln!(
            "[{}] {done}/{} items {msg}; {}",
            format_seconds(self.start.elapsed().as_secs_f64()),
            self.total,
            busy.join("; ")
        );
    }

    /// Clears the bars and returns what the workers did.
    pub fn finish(self) -> Counts {
        if let Some((_, main, lines)) = &self.bars {
            for l in lines {
                l.finish_and_clear();
            }
            main.finish_and_clear();
        }
        Counts {
            ok: self.ok,
            failed: self.failed,
            retried: self.retried,
            most_at_once: self.most_at_once,
        }
    }
}
