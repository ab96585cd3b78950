//! The local orchestrator's pool: a queue of shards, N slots each running one worker on one
//! shard, workers that write their shard while their slot already runs the next one
//! (overlapping writes), shards leased elsewhere waited for and taken over, the restart policy
//! (a worker killed by a signal is restarted; one that ends without finishing waits for the
//! shard's holder), stuck workers taken back (`stuck.rs`), a clean stop on request, and
//! progress through an [`Observer`].
//!
//! How workers start, what a shard's state is and how progress shows are the caller's
//! ([`Launcher`], [`Observer`]): `run` starts `sparc3d work --events` processes
//! (`local_workers.rs`); the unit tests below start fakes.

use crate::run::stuck::Watch;
use anyhow::Result;
use sparc3d_workers::lease::LeaseInfo;
use sparc3d_workers::shard::events::Event;
use sparc3d_workers::shard::lanes::Share;
use sparc3d_workers::store::state::ShardState;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::os::unix::process::ExitStatusExt;
use std::process::ExitStatus;
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::{Duration, Instant};

/// Times a shard's worker may be killed by a signal before the run gives up on it.
const MAX_WORKER_DEATHS: u32 = 20;

/// Times a shard's worker may end without finishing it (its lease was held elsewhere) before
/// the run gives up on it.
const MAX_UNFINISHED_EXITS: u32 = 1000;

/// How often shards leased by other workers are looked at again.
const WAIT_POLL: Duration = Duration::from_millis(250);

/// A worker running one shard.
pub trait Worker {
    /// Its exit status, once it has exited.
    fn try_wait(&mut self) -> Option<ExitStatus>;
    /// Asks it to stop cleanly (SIGTERM for a process).
    fn terminate(&mut self);
    /// Kills it at once (SIGKILL for a process): it is stuck.
    fn kill(&mut self);
    /// Its process id, as its shard's lease names it.
    fn pid(&self) -> u32;
    /// The end of its error output, once it has exited (empty when it printed none).
    fn error_tail(&mut self) -> String;
    /// Gives it a new share of the machine (items at once, threads each).
    fn set_share(&mut self, share: Share);
}

/// Starts workers and reads shards' states: the pool's view of the job.
pub trait Launcher {
    /// The workers it starts.
    type Worker: Worker;
    /// Starts a worker on `shard` in `slot`; it reports on `events`, tagged with its slot.
    fn spawn(
        &mut self,
        shard: u64,
        slot: usize,
        events: &Sender<(usize, Event)>,
    ) -> Result<Self::Worker>;
    /// The state of `shard` now.
    fn shard_state(&mut self, shard: u64) -> Result<ShardState>;
    /// The lease of `shard` as its file says, expired or not (`None`: none readable).
    fn lease(&mut self, shard: u64) -> Option<LeaseInfo>;
}

/// Where the pool reports progress.
pub trait Observer {
    /// `slot` now runs `shard` (`None`: it is free).
    fn slot_shard(&mut self, slot: usize, shard: Option<u64>);
    /// The worker in `slot` started the item `uri`.
    fn item_started(&mut self, slot: usize, uri: &str);
    /// The worker in `slot` finished an item with `status`.
    fn item_finished(&mut self, slot: usize, status: &str);
    /// A line about a shard (shown above any progress bars).
    fn println(&self, line: &str);
    /// Called once per turn of the loop (periodic log lines).
    fn tick(&mut self);
}

impl Observer for crate::run::progress::Progress {
    fn slot_shard(&mut self, slot: usize, shard: Option<u64>) {
        crate::run::progress::Progress::slot_shard(self, slot, shard)
    }
    fn item_started(&mut self, slot: usize, uri: &str) {
        crate::run::progress::Progress::item_started(self, slot, uri)
    }
    fn item_finished(&mut self, slot: usize, status: &str) {
        crate::run::progress::Progress::item_finished(self, slot, status)
    }
    fn println(&self, line: &str) {
        crate::run::progress::Progress::println(self, line)
    }
    fn tick(&mut self) {
        crate::run::progress::Progress::tick(self)
    }
}

/// A worker and the shard it runs.
struct Running<W> {
    worker: W,
    shard: u64,
    /// Whether it makes progress (its lease).
    watch: Watch,
    /// Items it converts at once (its share of the pool's lanes).
    lanes: usize,
    /// Items of its shard not finished yet, once it said (its `ShardStarted` event).
    left: Option<u64>,
}

impl<W: Worker> Running<W> {
    fn new(worker: W, shard: u64) -> Self {
        Self {
            worker,
            shard,
            watch: Watch::new(),
            lanes: 1,
            left: None,
        }
    }

    /// Follows its shard's items left from its events.
    fn count(&mut self, e: &Event) {
        match e {
            Event::ShardStarted { items, done, .. } => {
                self.left = Some(items.saturating_sub(*done))
            }
            Event::ItemFinished { status, .. } if status != "retry" => {
                self.left = self.left.map(|n| n.saturating_sub(1));
            }
            _ => {}
        }
    }
}

/// The shards to start now, and those leased by another live worker (to wait for, with the
/// holder), from the shards' states; damaged and leased shards are reported to `observer`.
pub fn plan(
    states: &[ShardState],
    observer: &dyn Observer,
) -> (VecDeque<u64>, BTreeMap<u64, String>) {
    let mut queue = VecDeque::new();
    let mut waiting = BTreeMap::new();
    for (shard, state) in (0..).zip(states) {
        match state {
            ShardState::Done(_) => {}
            ShardState::Running(l) => {
                observer.println(&format!(
                    "shard {shard}: leased by {}; waiting for it to finish or its lease to expire",
                    l.owner
                ));
                waiting.insert(shard, l.owner.clone());
            }
            ShardState::Damaged(why) => {
                observer.println(&format!(
                    "shard {shard}: damaged ({why}); converting it again"
                ));
                queue.push_back(shard);
            }
            ShardState::Pending => queue.push_back(shard),
        }
    }
    (queue, waiting)
}

/// The pool of worker slots over a job's shards. Its lanes (as many as slots) are spread over
/// the running workers ([`crate::run::lane_plan`]): a slot left free because no shard is queued
/// lends its lane to a worker with items left.
pub struct Pool<L: Launcher> {
    launcher: L,
    /// Threads per lane given with each share (0: the workers' environment decides).
    threads: usize,
    queue: VecDeque<u64>,
    waiting: BTreeMap<u64, String>,
    slots: Vec<Option<Running<L::Worker>>>,
    /// Workers whose items are all done and that are writing their shard: their slot already
    /// runs the next shard, so writing overlaps converting.
    writing: Vec<Running<L::Worker>>,
    killed: HashMap<u64, u32>,
    unfinished: HashMap<u64, u32>,
    errors: Vec<String>,
    last_look: Instant,
    /// Seconds a worker's lease lives without a heartbeat.
    lease_ttl: Duration,
    last_watch: Instant,
    /// Workers' events, tagged with their slot: the sender given to each, and the receiver.
    events_tx: Sender<(usize, Event)>,
    events: Receiver<(usize, Event)>,
}

impl<L: Launcher> Pool<L> {
    /// A pool of `workers` slots over the shards `queue` (to start) and `waiting` (leased
    /// elsewhere), as [`plan`] gives them; the workers' leases live `lease_ttl` without a
    /// heartbeat.
    pub fn new(
        launcher: L,
        workers: usize,
        queue: VecDeque<u64>,
        waiting: BTreeMap<u64, String>,
        lease_ttl: Duration,
    ) -> Self {
        let (events_tx, events) = mpsc::channel();
        Self {
            launcher,
            threads: 0,
            queue,
            waiting,
            slots: (0..workers.max(1)).map(|_| None).collect(),
            writing: Vec::new(),
            killed: HashMap::new(),
            unfinished: HashMap::new(),
            errors: Vec::new(),
            last_look: Instant::now(),
            lease_ttl,
            last_watch: Instant::now(),
            events_tx,
            events,
        }
    }

    /// Gives each lane `threads` threads (0, the default: as the workers' environment says).
    pub fn with_threads(mut self, threads: usize) -> Self {
        self.threads = threads;
        self
    }

    /// Runs workers until every shard is finished or given up, or until `stop()` turns true
    /// (then the workers are asked to stop and waited for). Returns the shards given up on,
    /// one message each.
    pub fn run(
        mut self,
        observer: &mut dyn Observer,
        stop: &dyn Fn() -> bool,
    ) -> Result<Vec<String>> {
        let mut signalled = false;
        loop {
            let stopping = stop();
            if !stopping {
                self.fill_slots(observer)?;
            }
            if stopping && !signalled {
                signalled = true;
                for r in self.slots.iter_mut().flatten() {
                    r.worker.terminate();
                }
            }
            if !stopping {
                self.look_at_waiting()?;
            }
            // Also while stopping: a stopped worker never acts on SIGTERM.
            self.take_back_stuck(observer, stopping);
            if self.slots.iter().all(Option::is_none)
                && self.writing.is_empty()
                && ((self.queue.is_empty() && self.waiting.is_empty()) || stopping)
            {
                break;
            }
            self.take_events(observer);
            if !stopping {
                self.share_lanes();
            }
            for (slot, r, status) in self.exited() {
                if let Some(slot) = slot {
                    observer.slot_shard(slot, None);
                }
                if !stop() {
                    self.after_exit(r, status, observer)?;
                }
            }
            observer.tick();
        }
        // The last events.
        while let Ok((slot, e)) = self.events.try_recv() {
            if let Event::ItemFinished { status, .. } = e {
                observer.item_finished(slot, &status);
            }
        }
        Ok(self.errors)
    }

    /// Starts the next shards in the free slots, as far as free lanes allow.
    fn fill_slots(&mut self, observer: &mut dyn Observer) -> Result<()> {
        let used: usize = self.slots.iter().flatten().map(|r| r.lanes).sum();
        let mut free = self.slots.len().saturating_sub(used);
        for (slot, s) in self.slots.iter_mut().enumerate() {
            if free == 0 {
                break;
            }
            if s.is_none() {
                let Some(shard) = self.queue.pop_front() else {
                    break;
                };
                let worker = self.launcher.spawn(shard, slot, &self.events_tx)?;
                *s = Some(Running::new(worker, shard));
                observer.slot_shard(slot, Some(shard));
                free -= 1;
            }
        }
        Ok(())
    }

    /// Spreads the lanes over the running workers again, telling those whose share changed.
    fn share_lanes(&mut self) {
        let holders: Vec<crate::run::lane_plan::Holder> = self
            .slots
            .iter()
            .flatten()
            .map(|r| crate::run::lane_plan::Holder { left: r.left })
            .collect();
        let lanes = crate::run::lane_plan::share(self.slots.len(), &holders, self.queue.len());
        for (r, lanes) in self.slots.iter_mut().flatten().zip(lanes) {
            if r.lanes != lanes {
                r.lanes = lanes;
                r.worker.set_share(Share {
                    lanes,
                    threads: self.threads,
                });
            }
        }
    }

    /// Shards held elsewhere: finished there, or free to take over.
    fn look_at_waiting(&mut self) -> Result<()> {
        if self.waiting.is_empty() || self.last_look.elapsed() < WAIT_POLL {
            return Ok(());
        }
        self.last_look = Instant::now();
        let mut free = Vec::new();
        for &shard in self.waiting.keys() {
            match self.launcher.shard_state(shard)? {
                ShardState::Running(_) => {}
                ShardState::Done(_) => free.push((shard, false)),
                ShardState::Pending | ShardState::Damaged(_) => free.push((shard, true)),
            }
        }
        for (shard, todo) in free {
            self.waiting.remove(&shard);
            if todo {
                self.queue.push_back(shard);
            }
        }
        Ok(())
    }

    /// Workers that make no progress past their lease (stopped, hung): killed, and their
    /// shard started again on a new worker, which takes the expired lease over (unless the
    /// pool is `stopping`).
    fn take_back_stuck(&mut self, observer: &dyn Observer, stopping: bool) {
        if self.last_watch.elapsed() < WAIT_POLL {
            return;
        }
        self.last_watch = Instant::now();
        let now = sparc3d_workers::clock::now();
        let running = self
            .slots
            .iter_mut()
            .flatten()
            .chain(self.writing.iter_mut());
        for r in running {
            let lease = self.launcher.lease(r.shard);
            let pid = r.worker.pid();
            if let Some(why) = r.watch.look(lease.as_ref(), pid, now, self.lease_ttl) {
                r.worker.kill();
                let next = if stopping {
                    ""
                } else {
                    " and starting the shard again on a new worker"
                };
                observer.println(&format!(
                    "shard {}: worker {pid} made no progress past its lease ({why}); killed it{next}",
                    r.shard
                ));
            }
        }
    }

    /// Shows the workers' events (waiting briefly for the first); a worker writing its shard
    /// leaves its slot for the next shard.
    fn take_events(&mut self, observer: &mut dyn Observer) {
        let mut next = self.events.recv_timeout(Duration::from_millis(20)).ok();
        while let Some((slot, e)) = next {
            if let Some(r) = self.slots[slot].as_mut() {
                r.watch.saw_event();
                r.count(&e);
            }
            match e {
                Event::ItemStarted { uri, .. } => observer.item_started(slot, &uri),
                Event::ItemFinished { status, .. } => observer.item_finished(slot, &status),
                Event::ShardSkipped { shard, reason } => {
                    observer.println(&format!("shard {shard}: {reason}"))
                }
                Event::LeaseLost { message, .. } => observer.println(&message),
                Event::ShardDamaged {
                    shard,
                    reason,
                    moved_to,
                } => observer.println(&format!(
                    "shard {shard}: damaged ({reason}); moved aside to {moved_to}, converting it \
                     again"
                )),
                Event::ShardWriting { shard } => {
                    if let Some(r) = self.slots[slot].take_if(|r| r.shard == shard) {
                        self.writing.push(r);
                        observer.slot_shard(slot, None);
                    }
                }
                _ => {}
            }
            next = self.events.try_recv().ok();
        }
    }

    /// Writers that exited, then slot workers that exited (with their slot).
    fn exited(&mut self) -> Vec<(Option<usize>, Running<L::Worker>, ExitStatus)> {
        let mut exited = Vec::new();
        let mut i = 0;
        while i < self.writing.len() {
            match self.writing[i].worker.try_wait() {
                Some(status) => exited.push((None, self.writing.swap_remove(i), status)),
                None => i += 1,
            }
        }
        for (slot, s) in self.slots.iter_mut().enumerate() {
            if let Some(status) = s.as_mut().and_then(|r| r.worker.try_wait()) {
                if let Some(r) = s.take() {
                    exited.push((Some(slot), r, status));
                }
            }
        }
        exited
    }

    /// The restart policy for a worker that exited.
    fn after_exit(
        &mut self,
        mut r: Running<L::Worker>,
        status: ExitStatus,
        observer: &dyn Observer,
    ) -> Result<()> {
        if status.success() {
            // Done, or held by another worker (it said "leased by"): wait for that one.
            return self.after_success(r.shard, observer);
        }
        if r.watch.taken_back() {
            // Killed by `take_back_stuck`, which said so; its journal keeps its finished items.
            self.queue.push_back(r.shard);
            return Ok(());
        }
        let deaths = self.killed.entry(r.shard).or_insert(0);
        if status.signal().is_some() && *deaths < MAX_WORKER_DEATHS {
            // Killed from outside (kill -9, OOM killer): the journal keeps its finished
            // items; a new worker takes the shard over.
            *deaths += 1;
            observer.println(&format!(
                "shard {}: worker {status}; restarting it",
                r.shard
            ));
            self.queue.push_back(r.shard);
            return Ok(());
        }
        let tail = r.worker.error_tail();
        let reason = if tail.is_empty() {
            "the worker printed no error".to_string()
        } else {
            tail
        };
        // This shard is left for a later run; the others go on.
        let msg = format!("shard {} failed ({status}): {reason}", r.shard);
        observer.println(&msg);
        self.errors.push(msg);
        Ok(())
    }

    /// A worker that exited with success: its shard is done, or another worker holds it.
    fn after_success(&mut self, shard: u64, observer: &dyn Observer) -> Result<()> {
        match self.launcher.shard_state(shard)? {
            ShardState::Done(_) => {}
            other => {
                let n = self.unfinished.entry(shard).or_insert(0);
                *n += 1;
                if *n > MAX_UNFINISHED_EXITS {
                    let msg =
                        format!("shard {shard} is still not finished after {n} tries ({other:?})");
                    observer.println(&msg);
                    self.errors.push(msg);
                } else {
                    let holder = match other {
                        ShardState::Running(l) => l.owner,
                        _ => "another worker".into(),
                    };
                    self.waiting.insert(shard, holder);
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sparc3d_schema::CompletionRecord;
    use std::cell::RefCell;
    use std::rc::Rc;

    /// What a fake worker does with its shard.
    #[derive(Debug, Clone, Copy, PartialEq)]
    enum Script {
        /// Finishes the shard and exits 0.
        Finish,
        /// Finishes the shard after a while.
        FinishSlowly,
        /// Says it is writing (leaving its slot), then finishes after a while.
        WriteSlowly,
        /// Is killed by SIGKILL.
        Killed,
        /// Exits 1 with an error.
        Fail,
        /// Exits 0 without finishing (another worker holds the shard).
        LeasedElsewhere,
        /// Runs until it is asked to stop.
        RunForever,
        /// Runs until killed; its lease expired (a stopped worker).
        Stuck,
    }

    #[derive(Default)]
    struct World {
        scripts: HashMap<u64, VecDeque<Script>>,
        states: HashMap<u64, ShardState>,
        spawned: Vec<(u64, usize)>,
        leases: HashMap<u64, LeaseInfo>,
        alive: usize,
        most_alive: usize,
        terminated: usize,
        killed: Vec<u32>,
        /// Shares given to workers: (shard, lanes).
        shares: Vec<(u64, usize)>,
    }

    struct FakeWorker {
        world: Rc<RefCell<World>>,
        shard: u64,
        script: Script,
        turns_left: u32,
        stopped: bool,
        killed: bool,
        pid: u32,
    }

    fn done(shard: u64) -> ShardState {
        ShardState::Done(CompletionRecord {
            shard,
            schema_version: 2,
            rows: 1,
            ok: 1,
            ..Default::default()
        })
    }

    fn leased() -> ShardState {
        ShardState::Running(LeaseInfo {
            owner: "elsewhere:1:x".into(),
            host: "elsewhere".into(),
            pid: 1,
            heartbeat_at: 0.0,
            expires_at: 0.0,
            acquired_at: 0.0,
        })
    }

    impl Worker for FakeWorker {
        fn try_wait(&mut self) -> Option<ExitStatus> {
            let forever = matches!(self.script, Script::RunForever | Script::Stuck);
            if !self.stopped && !self.killed && (forever || self.turns_left > 0) {
                self.turns_left = self.turns_left.saturating_sub(1);
                return None;
            }
            let mut w = self.world.borrow_mut();
            w.alive -= 1;
            let raw = match self.script {
                _ if self.killed => libc::SIGKILL,
                _ if self.stopped => 0,
                Script::Finish | Script::FinishSlowly | Script::WriteSlowly => {
                    w.states.insert(self.shard, done(self.shard));
                    0
                }
                Script::LeasedElsewhere | Script::RunForever | Script::Stuck => 0,
                Script::Killed => libc::SIGKILL,
                Script::Fail => 1 << 8,
            };
            self.turns_left = u32::MAX;
            self.stopped = true;
            Some(ExitStatus::from_raw(raw))
        }
        fn terminate(&mut self) {
            self.stopped = true;
            self.world.borrow_mut().terminated += 1;
        }
        fn kill(&mut self) {
            self.killed = true;
            self.world.borrow_mut().killed.push(self.pid);
        }
        fn pid(&self) -> u32 {
            self.pid
        }
        fn error_tail(&mut self) -> String {
            "error: no such mesh".into()
        }
        fn set_share(&mut self, share: Share) {
            self.world
                .borrow_mut()
                .shares
                .push((self.shard, share.lanes));
        }
    }

    struct FakeLauncher {
        world: Rc<RefCell<World>>,
        start: Instant,
        /// Shards' states set by others once the given time has passed.
        changes: Vec<(Duration, u64, ShardState)>,
    }

    impl Launcher for FakeLauncher {
        type Worker = FakeWorker;
        fn spawn(
            &mut self,
            shard: u64,
            slot: usize,
            events: &Sender<(usize, Event)>,
        ) -> Result<FakeWorker> {
            let mut w = self.world.borrow_mut();
            let script = w
                .scripts
                .get_mut(&shard)
                .and_then(VecDeque::pop_front)
                .unwrap_or(Script::Finish);
            w.spawned.push((shard, slot));
            let pid = 1000 + w.spawned.len() as u32;
            w.alive += 1;
            w.most_alive = w.most_alive.max(w.alive);
            if script == Script::Stuck {
                // Its lease, last renewed long ago: it expired.
                let lease = LeaseInfo {
                    owner: format!("here:{pid}:0"),
                    host: sparc3d_workers::lease::hostname(),
                    pid,
                    heartbeat_at: 0.0,
                    expires_at: 60.0,
                    acquired_at: 0.0,
                };
                w.leases.insert(shard, lease);
            }
            if script == Script::WriteSlowly {
                events.send((slot, Event::ShardWriting { shard }))?;
            }
            let turns_left = match script {
                Script::WriteSlowly | Script::FinishSlowly => 10,
                _ => 2,
            };
            Ok(FakeWorker {
                world: self.world.clone(),
                shard,
                script,
                turns_left,
                stopped: false,
                killed: false,
                pid,
            })
        }
        fn lease(&mut self, shard: u64) -> Option<LeaseInfo> {
            self.world.borrow().leases.get(&shard).cloned()
        }
        fn shard_state(&mut self, shard: u64) -> Result<ShardState> {
            let mut w = self.world.borrow_mut();
            let now = self.start.elapsed();
            for (_, s, state) in self.changes.iter().filter(|(at, _, _)| *at <= now) {
                w.states.insert(*s, state.clone());
            }
            self.changes.retain(|(at, _, _)| *at > now);
            Ok(w.states.get(&shard).cloned().unwrap_or(ShardState::Pending))
        }
    }

    #[derive(Default)]
    struct Seen {
        lines: RefCell<Vec<String>>,
    }

    impl Observer for Seen {
        fn slot_shard(&mut self, _: usize, _: Option<u64>) {}
        fn item_started(&mut self, _: usize, _: &str) {}
        fn item_finished(&mut self, _: usize, _: &str) {}
        fn println(&self, line: &str) {
            self.lines.borrow_mut().push(line.to_string());
        }
        fn tick(&mut self) {}
    }

    /// Runs a pool of `workers` slots over `shards` shards with `scripts`, from `states`
    /// (shards not named are pending) changed by others at the given times; the world after
    /// it, the errors and the lines shown.
    fn run_pool(
        shards: u64,
        workers: usize,
        scripts: &[(u64, &[Script])],
        states: &[(u64, ShardState)],
        changes: &[(Duration, u64, ShardState)],
        stop: &dyn Fn() -> bool,
    ) -> Result<(World, Vec<String>, Vec<String>)> {
        let world = Rc::new(RefCell::new(World::default()));
        {
            let mut w = world.borrow_mut();
            for (shard, s) in scripts {
                w.scripts.insert(*shard, s.iter().copied().collect());
            }
            w.states.extend(states.iter().cloned());
        }
        let all: Vec<ShardState> = (0..shards)
            .map(|s| {
                world
                    .borrow()
                    .states
                    .get(&s)
                    .cloned()
                    .unwrap_or(ShardState::Pending)
            })
            .collect();
        let mut seen = Seen::default();
        let (queue, waiting) = plan(&all, &seen);
        let launcher = FakeLauncher {
            world: world.clone(),
            start: Instant::now(),
            changes: changes.to_vec(),
        };
        let pool = Pool::new(launcher, workers, queue, waiting, Duration::from_secs(60));
        let errors = pool.run(&mut seen, stop)?;
        let world = Rc::try_unwrap(world)
            .map_err(|_| anyhow::anyhow!("a fake worker outlived the pool"))?
            .into_inner();
        Ok((world, errors, seen.lines.into_inner()))
    }

    fn spawns_of(world: &World, shard: u64) -> usize {
        world.spawned.iter().filter(|(s, _)| *s == shard).count()
    }

    #[test]
    fn runs_every_shard_once_in_at_most_n_slots_and_ends_when_none_is_left() -> Result<()> {
        let (world, errors, _) = run_pool(5, 2, &[], &[(3, done(3))], &[], &|| false)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(world.most_alive, 2);
        assert_eq!(world.alive, 0);
        let shards: Vec<u64> = world.spawned.iter().map(|(s, _)| *s).collect();
        assert_eq!(shards, vec![0, 1, 2, 4], "a done shard is not started");
        assert!(world.spawned.iter().all(|(_, slot)| *slot < 2));
        Ok(())
    }

    #[test]
    fn a_killed_worker_is_restarted_and_a_failed_one_is_reported() -> Result<()> {
        use Script::*;
        let scripts: &[(u64, &[Script])] = &[(0, &[Killed, Killed, Finish]), (1, &[Fail])];
        let (world, errors, lines) = run_pool(2, 2, scripts, &[], &[], &|| false)?;
        assert_eq!(spawns_of(&world, 0), 3);
        assert!(matches!(world.states.get(&0), Some(ShardState::Done(_))));
        assert_eq!(
            spawns_of(&world, 1),
            1,
            "a worker that failed is not restarted"
        );
        assert_eq!(errors.len(), 1);
        assert!(errors[0].starts_with("shard 1 failed (exit status: 1): error: no such mesh"));
        let restarts = lines
            .iter()
            .filter(|l| l.ends_with("restarting it"))
            .count();
        assert_eq!(restarts, 2);
        Ok(())
    }

    #[test]
    fn a_shard_whose_worker_keeps_being_killed_is_given_up() -> Result<()> {
        let killed = [Script::Killed; MAX_WORKER_DEATHS as usize + 1];
        let (world, errors, _) = run_pool(1, 1, &[(0, &killed)], &[], &[], &|| false)?;
        assert_eq!(spawns_of(&world, 0), MAX_WORKER_DEATHS as usize + 1);
        assert_eq!(errors.len(), 1);
        assert!(errors[0].contains("signal: 9"), "{errors:?}");
        Ok(())
    }

    #[test]
    fn a_writing_worker_leaves_its_slot_to_the_next_shard() -> Result<()> {
        let scripts: &[(u64, &[Script])] = &[(0, &[Script::WriteSlowly])];
        let (world, errors, _) = run_pool(2, 1, scripts, &[], &[], &|| false)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(world.spawned, vec![(0, 0), (1, 0)]);
        assert_eq!(
            world.most_alive, 2,
            "shard 1 converted while shard 0 was written"
        );
        assert!(matches!(world.states.get(&0), Some(ShardState::Done(_))));
        Ok(())
    }

    #[test]
    fn a_shard_leased_elsewhere_is_waited_for_and_taken_over_once_free() -> Result<()> {
        // Shard 0 is leased elsewhere from the start; shard 1's worker finds it leased by
        // another worker and ends. Later the lease of 0 expires and 1 is finished there.
        let scripts: &[(u64, &[Script])] = &[(1, &[Script::LeasedElsewhere])];
        let soon = Duration::ZERO;
        let later = Duration::from_millis(300);
        let changes = [
            (soon, 1, leased()),
            (later, 0, ShardState::Pending),
            (later, 1, done(1)),
        ];
        let (world, errors, lines) =
            run_pool(2, 1, scripts, &[(0, leased())], &changes, &|| false)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert!(lines[0].starts_with("shard 0: leased by elsewhere:1:x; waiting"));
        assert_eq!(spawns_of(&world, 0), 1, "taken over once its lease expired");
        assert_eq!(
            spawns_of(&world, 1),
            1,
            "finished by its holder: not started again"
        );
        Ok(())
    }

    #[test]
    fn a_stop_request_stops_the_workers_and_ends_the_pool() -> Result<()> {
        let forever: &[Script] = &[Script::RunForever];
        let start = Instant::now();
        let stop = move || start.elapsed() > Duration::from_millis(100);
        let (world, errors, _) = run_pool(3, 2, &[(0, forever), (1, forever)], &[], &[], &stop)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(world.terminated, 2);
        assert_eq!(spawns_of(&world, 2), 0, "no shard starts after the request");
        assert_eq!(world.alive, 0, "the pool waits for its workers");
        Ok(())
    }

    /// Issue 32, item 6: a worker whose own lease expired (stopped) is killed, said so, and
    /// its shard started again on a new worker; the other shards go on.
    #[test]
    fn a_worker_stuck_past_its_lease_is_killed_and_its_shard_started_again() -> Result<()> {
        let scripts: &[(u64, &[Script])] = &[(0, &[Script::Stuck, Script::Finish])];
        let (world, errors, lines) = run_pool(2, 2, scripts, &[], &[], &|| false)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(world.killed, vec![1001], "the stuck worker is killed");
        assert_eq!(spawns_of(&world, 0), 2, "its shard started again");
        assert!(matches!(world.states.get(&0), Some(ShardState::Done(_))));
        assert!(matches!(world.states.get(&1), Some(ShardState::Done(_))));
        let said: Vec<&String> = lines.iter().filter(|l| l.contains("lease")).collect();
        assert_eq!(said.len(), 1, "{lines:?}");
        assert!(
            said[0].starts_with(
                "shard 0: worker 1001 made no progress past its lease (its lease expired"
            ) && said[0].ends_with("starting the shard again on a new worker"),
            "{}",
            said[0]
        );
        assert!(
            !lines.iter().any(|l| l.ends_with("restarting it")),
            "{lines:?}"
        );
        Ok(())
    }

    /// Issue 46: a job of one shard keeps every lane busy.
    #[test]
    fn a_lone_shard_gets_every_lane() -> Result<()> {
        let (world, errors, _) = run_pool(1, 3, &[], &[], &[], &|| false)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(world.spawned, vec![(0, 0)], "one worker for one shard");
        assert_eq!(world.shares, vec![(0, 3)]);
        Ok(())
    }

    /// Issue 46: the lane of a worker that finished goes to the one with items left; while
    /// shards are queued, each worker converts one item at a time.
    #[test]
    fn a_finished_workers_lane_goes_to_the_shard_still_converting() -> Result<()> {
        let scripts: &[(u64, &[Script])] = &[(2, &[Script::FinishSlowly])];
        let (world, errors, _) = run_pool(3, 2, scripts, &[], &[], &|| false)?;
        assert!(errors.is_empty(), "{errors:?}");
        assert_eq!(world.most_alive, 2);
        assert_eq!(world.shares, vec![(2, 2)], "{:?}", world.shares);
        Ok(())
    }
}
