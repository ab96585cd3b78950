//! The loop over a shard's unfinished items: up to the budget's lanes ([`crate::shard::lanes`])
//! convert at once, each lane in its own supervised item worker. This thread alone journals
//! every start, result, crash and abort (each append fenced by the lease), so a shard keeps one
//! writer whatever the lanes; rows are written in item order whatever order they finish in,
//! so the shard is the same for any number of lanes. With one lane it is the sequential loop.

use crate::error::{Result, WorkerError};
use crate::isolate::supervisor::{ItemOutcome, ItemRunner};
use crate::journal::record::Record;
use crate::journal::Journal;
use crate::lease::Lease;
use crate::shard::events::Event;
use crate::store::write::ShardStream;
use crate::work_options::WorkOptions;
use sparc3d_schema::{ErrorClass, FrozenItem, ItemStatus, JobConfig, ShardRow};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};

/// How often the loop looks at the stop flag and the budget while items convert.
const POLL: Duration = Duration::from_millis(50);

/// How the loop over a shard's items ended.
pub(crate) enum LoopEnd {
    /// Every item has its final row in the journal.
    Finished,
    /// A stop was requested; the items in flight were journalled as aborted.
    Stopped,
}

/// The shard being worked on: what every step of the loop needs besides the journal.
pub(crate) struct ShardWork<'a> {
    /// Shard index.
    pub shard: u64,
    /// The lease this worker holds on it.
    pub held: &'a Lease,
    /// The job's config (for the item workers).
    pub config: &'a JobConfig,
    /// Options of this run (events, limits, stop flag, budget).
    pub opts: &'a mut WorkOptions,
    /// The shard file, written as the items finish in order.
    pub stream: &'a mut ShardStream,
}

/// An item handed to a lane.
struct Task<'i> {
    item: &'i FrozenItem,
    /// Attempts started before this one.
    started: u32,
    threads: usize,
}

/// A lane's answer for one task.
struct Answer<'i> {
    lane: usize,
    item: &'i FrozenItem,
    started: u32,
    outcome: Result<ItemOutcome>,
    seconds: f64,
}

/// A lane: its task channel and whether it converts an item now.
struct LaneHandle<'i> {
    tasks: Sender<Task<'i>>,
    busy: bool,
}

/// What a settled answer asks of the loop.
enum Settled {
    Finished,
    Retry,
    Stopped,
}

/// Converts every item of `items` that `journal` does not hold yet, up to the budget's lanes
/// at once, journalling each outcome.
pub(crate) fn run_items(
    work: &mut ShardWork<'_>,
    journal: &mut Journal,
    items: &[FrozenItem],
) -> Result<LoopEnd> {
    let stop_flag = work.opts.stop.clone();
    let abort = AtomicBool::new(false);
    let held = work.held;
    let stop =
        || stop_flag.load(Ordering::SeqCst) || held.is_lost() || abort.load(Ordering::SeqCst);
    let queue: VecDeque<&FrozenItem> = items
        .iter()
        .filter(|i| !journal.state.done.contains_key(&i.index))
        .collect();
    std::thread::scope(|scope| {
        let (answers_tx, answers) = mpsc::channel();
        let mut lanes = Lanes {
            scope,
            handles: Vec::new(),
            answers_tx,
            stop: &stop,
        };
        let end = drive(work, journal, queue, &mut lanes, &answers);
        if end.is_err() {
            // The items in flight stop; nothing more is journalled.
            abort.store(true, Ordering::SeqCst);
        }
        drop(lanes);
        end
    })
}

/// The lanes of one loop: threads of a scope, each with its own item worker; the items and
/// the stop condition they borrow live outside the scope (`'e`).
struct Lanes<'s, 'e, S: Fn() -> bool + Sync> {
    scope: &'s std::thread::Scope<'s, 'e>,
    handles: Vec<LaneHandle<'e>>,
    answers_tx: Sender<Answer<'e>>,
    stop: &'e S,
}

impl<'s, 'e, S: Fn() -> bool + Sync> Lanes<'s, 'e, S> {
    /// An idle lane's index, starting a new one (with its item worker) when all are busy.
    fn idle(&mut self, work: &ShardWork<'_>) -> Result<usize> {
        if let Some(i) = self.handles.iter().position(|h| !h.busy) {
            return Ok(i);
        }
        let lane = self.handles.len();
        let mut runner = ItemRunner::new(work.opts.child.clone(), work.config, work.opts.limits)?;
        let (tasks, inbox) = mpsc::channel::<Task<'e>>();
        let answers = self.answers_tx.clone();
        let stop = self.stop;
        std::thread::Builder::new()
            .name(format!("lane-{lane}"))
            .spawn_scoped(self.scope, move || {
                serve(lane, &mut runner, &inbox, &answers, stop)
            })
            .map_err(|e| WorkerError::Child(format!("starting lane {lane}: {e}")))?;
        self.handles.push(LaneHandle { tasks, busy: false });
        Ok(lane)
    }
}

/// A lane's life: convert each task it is given, answer with its outcome.
fn serve<'i>(
    lane: usize,
    runner: &mut ItemRunner,
    inbox: &Receiver<Task<'i>>,
    answers: &Sender<Answer<'i>>,
    stop: &(dyn Fn() -> bool + Sync),
) {
    for task in inbox {
        runner.set_threads(task.threads);
        let t = Instant::now();
        let outcome = runner.run(task.item, stop);
        let answer = Answer {
            lane,
            item: task.item,
            started: task.started,
            outcome,
            seconds: t.elapsed().as_secs_f64(),
        };
        if answers.send(answer).is_err() {
            return;
        }
    }
}

/// The loop itself: start items while lanes are free, settle answers as they come.
fn drive<'e, S: Fn() -> bool + Sync>(
    work: &mut ShardWork<'_>,
    journal: &mut Journal,
    mut queue: VecDeque<&'e FrozenItem>,
    lanes: &mut Lanes<'_, 'e, S>,
    answers: &Receiver<Answer<'e>>,
) -> Result<LoopEnd> {
    let mut running = 0usize;
    let mut stopping = false;
    loop {
        stopping |= work.opts.stop.load(Ordering::SeqCst);
        while !stopping && running < work.opts.budget.lanes() {
            let Some(item) = queue.pop_front() else { break };
            let Some(started) = prepare(work, journal, item)? else {
                continue;
            };
            let concurrent = (running + 1 + queue.len()).min(work.opts.budget.lanes());
            let task = Task {
                item,
                started,
                threads: work.opts.budget.threads_for(concurrent),
            };
            dispatch(work, journal, lanes, task)?;
            running += 1;
        }
        if running == 0 {
            // An item aborted by the stop is back in the queue: the shard is not finished.
            return Ok(if queue.is_empty() {
                LoopEnd::Finished
            } else {
                LoopEnd::Stopped
            });
        }
        let answer = match answers.recv_timeout(POLL) {
            Ok(a) => a,
            Err(RecvTimeoutError::Timeout) => continue,
            Err(RecvTimeoutError::Disconnected) => {
                return Err(WorkerError::Child("every lane ended".into()))
            }
        };
        running -= 1;
        lanes.handles[answer.lane].busy = false;
        let item = answer.item;
        match settle(work, journal, answer)? {
            Settled::Finished => {}
            Settled::Retry => queue.push_front(item),
            Settled::Stopped => {
                queue.push_front(item);
                stopping = true;
            }
        }
    }
}

/// Journals an item's start and hands it to an idle lane.
fn dispatch<'e, S: Fn() -> bool + Sync>(
    work: &mut ShardWork<'_>,
    journal: &mut Journal,
    lanes: &mut Lanes<'_, 'e, S>,
    task: Task<'e>,
) -> Result<()> {
    let lane = lanes.idle(work)?;
    let item = task.item;
    let start = Record::Start {
        index: item.index,
        attempt: task.started + 1,
        at: crate::clock::now(),
    };
    append(journal, work.held, work.shard, &start)?;
    (work.opts.events)(Event::ItemStarted {
        shard: work.shard,
        index: item.index,
        id: item.record.id.clone(),
        uri: item.record.uri.clone(),
    });
    lanes.handles[lane]
        .tasks
        .send(task)
        .map_err(|_| WorkerError::Child(format!("lane {lane} ended")))?;
    lanes.handles[lane].busy = true;
    Ok(())
}

/// The attempts `item` had so far, or `None` when it killed its worker too often and was given
/// up on now (its failed row journalled).
fn prepare(
    work: &mut ShardWork<'_>,
    journal: &mut Journal,
    item: &FrozenItem,
) -> Result<Option<u32>> {
    let attempts = journal
        .state
        .attempts
        .get(&item.index)
        .cloned()
        .unwrap_or_default();
    if attempts.interrupted() < work.opts.limits.max_interrupted_attempts {
        return Ok(Some(attempts.started));
    }
    let message = format!(
        "the worker was killed {} times while converting this item",
        attempts.interrupted()
    );
    let resolution = work.config.params.resolution;
    let mut row = ShardRow::failed_item(item, resolution, ErrorClass::Crashed, message);
    row.attempts = attempts.started;
    finish(work, journal, row)?;
    Ok(None)
}

/// Journals what a lane's answer says: the row, a crash to retry, or the abort.
fn settle(work: &mut ShardWork<'_>, journal: &mut Journal, a: Answer<'_>) -> Result<Settled> {
    let attempt = a.started + 1;
    match a.outcome? {
        ItemOutcome::Finished(mut row) => {
            row.attempts = attempt;
            row.timings.total_s = a.seconds;
            finish(work, journal, *row)?;
            Ok(Settled::Finished)
        }
        ItemOutcome::Stopped => {
            let abort = Record::Abort {
                index: a.item.index,
                at: crate::clock::now(),
            };
            append(journal, work.held, work.shard, &abort)?;
            Ok(Settled::Stopped)
        }
        ItemOutcome::Died {
            class,
            message,
            stderr_tail,
        } => {
            let crashes = journal
                .state
                .attempts
                .get(&a.item.index)
                .map_or(0, |x| x.crashes);
            if class.is_crash() && crashes < work.opts.limits.max_crash_retries {
                let crash = Record::Crash {
                    index: a.item.index,
                    class,
                    message,
                    at: crate::clock::now(),
                };
                append(journal, work.held, work.shard, &crash)?;
                (work.opts.events)(Event::ItemFinished {
                    shard: work.shard,
                    index: a.item.index,
                    status: "retry".into(),
                    class: Some(class.as_str().into()),
                    seconds: a.seconds,
                });
                return Ok(Settled::Retry);
            }
            let resolution = work.config.params.resolution;
            let mut row = ShardRow::failed_item(a.item, resolution, class, message);
            row.stderr_tail = (!stderr_tail.is_empty()).then_some(stderr_tail);
            row.attempts = attempt;
            row.timings.total_s = a.seconds;
            finish(work, journal, row)?;
            Ok(Settled::Finished)
        }
    }
}

/// `Ok` while this worker holds the lease of `shard`; else the error that stops it.
pub(crate) fn fence(held: &Lease, shard: u64) -> Result<()> {
    held.check().map_err(|loss| WorkerError::LeaseLost {
        shard,
        lease: loss.lease,
        why: loss.why,
    })
}

/// Appends `record` to this holder's journal once the lease is checked. A holder stopped
/// between the check and the write still writes only to its own file.
fn append(journal: &mut Journal, held: &Lease, shard: u64, record: &Record) -> Result<()> {
    fence(held, shard)?;
    journal.append(record)
}

/// Journals `row` as the item's final result and reports it.
fn finish(work: &mut ShardWork<'_>, journal: &mut Journal, row: ShardRow) -> Result<()> {
    let event = Event::ItemFinished {
        shard: work.shard,
        index: row.item_index,
        status: match row.status {
            ItemStatus::Ok => "ok",
            ItemStatus::Failed => "failed",
            ItemStatus::Skipped => "skipped",
        }
        .into(),
        class: row.error_class.map(|c| c.as_str().to_string()),
        seconds: row.timings.total_s,
    };
    let done = Record::Done {
        row: Box::new(row),
        at: crate::clock::now(),
    };
    append(journal, work.held, work.shard, &done)?;
    work.stream.catch_up(journal)?;
    (work.opts.events)(event);
    if let Some(checkpoint) = work.opts.after_item.as_mut() {
        checkpoint(journal)?;
    }
    Ok(())
}
