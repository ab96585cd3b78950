//! The rules of one shard, tested on the `sparc3d-workers` library alone (no CLI): resume from
//! a journal, retries of crashed items, giving up on an item that keeps killing its worker,
//! timeouts, stops, busy and finished shards. The item worker is a small shell script that
//! dies the way a real one can (killed by a signal, out of time), so every outcome here is
//! the supervisor's and the shard loop's.

use sparc3d_schema::{
    ErrorClass, FrozenItem, ItemStatus, JobConfig, JobFile, JobLayout, Limits, ManifestRecord,
    ShardRow,
};
use sparc3d_workers::isolate::supervisor::ChildCommand;
use sparc3d_workers::journal::record::Record;
use sparc3d_workers::journal::{self, Journal, JournalState};
use sparc3d_workers::lease::{self, Acquired};
use sparc3d_workers::store;
use sparc3d_workers::{process_shard, Job, ShardOutcome, WorkOptions};
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

type TestResult = Result<(), Box<dyn std::error::Error>>;

/// A job of `items` items (files that need not exist: the script never reads them), one
/// shard.
fn job(root: &Path, items: u64) -> Result<Job, Box<dyn std::error::Error>> {
    let config = JobConfig::default();
    let items: Vec<FrozenItem> = (0..items)
        .map(|i| FrozenItem {
            index: i,
            shard: 0,
            record: ManifestRecord {
                extra: Default::default(),
                id: format!("item{i}"),
                uri: root
                    .join(format!("m{i}.obj"))
                    .to_string_lossy()
                    .into_owned(),
                sha256: Some(format!("{i:064x}")),
                format: Some("obj".into()),
            },
        })
        .collect();
    let file = JobFile {
        schema_version: sparc3d_schema::SCHEMA_VERSION,
        tool_version: sparc3d_schema::TOOL_VERSION.into(),
        fingerprint: config.fingerprint()?,
        items: items.len() as u64,
        shards: 1,
        manifest_sha256: String::new(),
        manifest_pages: None,
        config,
    };
    Ok(Job {
        layout: JobLayout::new(root),
        file,
        manifest: sparc3d_workers::frozen::FrozenManifest::Whole(items),
    })
}

/// Every item of `job`.
fn all_items(job: &Job) -> Vec<FrozenItem> {
    job.items().collect::<Result<_, _>>().unwrap_or_default()
}

/// Options whose item worker runs `script` with `sh` (after reading the config and the
/// item lines the supervisor sends).
fn options(script: &str, limits: Limits, stop: bool) -> WorkOptions {
    WorkOptions {
        child: ChildCommand {
            program: "/bin/sh".into(),
            args: vec![
                "-c".into(),
                format!("read config; read item; {script}"),
                "sh".into(),
            ],
            env: Vec::new(),
        },
        limits,
        lease_ttl_s: 60.0,
        stop: Arc::new(AtomicBool::new(stop)),
        events: Box::new(|_| {}),
        after_item: None,
        budget: sparc3d_workers::shard::lanes::LaneBudget::single(),
    }
}

/// Dies by SIGKILL, as an item that takes its worker down does.
const KILLED: &str = "echo 'about to die' >&2; kill -9 $$";

fn rows(job: &Job) -> Result<Vec<ShardRow>, Box<dyn std::error::Error>> {
    Ok(store::read::read_rows(&job.layout.shard_file(0))?)
}

#[test]
fn a_crashing_item_is_retried_then_recorded_with_its_stderr() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 1)?;
    let limits = Limits {
        max_crash_retries: 2,
        ..Limits::default()
    };
    let outcome = process_shard(&job, 0, &mut options(KILLED, limits, false))?;
    assert!(matches!(outcome, ShardOutcome::Done(_)), "{outcome:?}");
    let rows = rows(&job)?;
    assert_eq!(rows.len(), 1);
    let row = &rows[0];
    assert_eq!(row.status, ItemStatus::Failed);
    assert_eq!(row.error_class, Some(ErrorClass::Crashed));
    assert_eq!(row.attempts, 3, "one try and two retries");
    let message = row.error_message.as_deref().unwrap_or_default();
    assert!(message.contains("signal 9"), "{message}");
    assert!(row
        .stderr_tail
        .as_deref()
        .is_some_and(|t| t.contains("about to die")));
    assert_eq!(row.source_sha256, all_items(&job)[0].record.sha256);
    // The journal is gone once the shard is written; the shard checks against its record.
    assert!(!journal::set::exists(&job.layout, 0));
    assert!(matches!(
        process_shard(&job, 0, &mut options(KILLED, limits, false))?,
        ShardOutcome::AlreadyDone(_)
    ));
    Ok(())
}

#[test]
fn an_item_out_of_time_is_failed_without_retry() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 1)?;
    let limits = Limits {
        item_timeout_s: 0.3,
        ..Limits::default()
    };
    process_shard(&job, 0, &mut options("exec sleep 30", limits, false))?;
    let row = &rows(&job)?[0];
    assert_eq!(row.error_class, Some(ErrorClass::Timeout));
    assert_eq!(row.attempts, 1, "timeouts are not retried");
    Ok(())
}

#[test]
fn resume_keeps_finished_items_and_gives_up_on_items_that_kill_their_worker() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 2)?;
    let limits = Limits::default();
    std::fs::create_dir_all(job.layout.state_dir())?;
    // A worker finished item 0, then was killed `max_interrupted_attempts` times on item 1.
    // Its journal is the single file earlier builds wrote: a job they started resumes.
    let mut journal = Journal::create(
        &job.layout.journal(0),
        0,
        job.fingerprint(),
        JournalState::default(),
    )?;
    let first = ShardRow::failed_item(
        &all_items(&job)[0],
        64,
        ErrorClass::Geometry(sparcubes::ErrorClass::ParseError),
        "from the journal".into(),
    );
    let start = |index, attempt| Record::Start {
        index,
        attempt,
        at: 1.0,
    };
    journal.append(&start(0, 1))?;
    journal.append(&Record::Done {
        row: Box::new(first.clone()),
        at: 2.0,
    })?;
    for attempt in 1..=limits.max_interrupted_attempts {
        journal.append(&start(1, attempt))?;
    }
    drop(journal);
    // Nothing may run: the script would turn item 1 into a crash.
    process_shard(&job, 0, &mut options(KILLED, limits, false))?;
    let rows = rows(&job)?;
    assert_eq!(rows[0], first, "the journaled row is written as it was");
    assert_eq!(rows[1].error_class, Some(ErrorClass::Crashed));
    assert_eq!(rows[1].attempts, limits.max_interrupted_attempts);
    let message = rows[1].error_message.as_deref().unwrap_or_default();
    assert!(message.contains("killed 5 times"), "{message}");
    assert!(!journal::set::exists(&job.layout, 0), "the journal is gone");
    Ok(())
}

#[test]
fn a_stop_during_an_item_leaves_the_journal_for_a_resume() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 1)?;
    let mut opts = options("exec sleep 30", Limits::default(), false);
    let stop = opts.stop.clone();
    let ctrl_c = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_millis(300));
        stop.store(true, std::sync::atomic::Ordering::SeqCst);
    });
    let outcome = process_shard(&job, 0, &mut opts)?;
    let _ = ctrl_c.join();
    assert_eq!(outcome, ShardOutcome::Stopped);
    assert!(!job.layout.shard_file(0).exists());
    let state = journal::set::read(&job.layout, 0, None)?;
    let attempts = &state.attempts[&0];
    assert_eq!((attempts.started, attempts.aborted), (1, 1));
    assert_eq!(
        attempts.interrupted(),
        0,
        "a stop is not held against the item"
    );
    Ok(())
}

#[test]
fn a_shard_leased_by_a_live_worker_is_left_alone() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 1)?;
    std::fs::create_dir_all(job.layout.state_dir())?;
    let Acquired::Held(held) = lease::acquire(&job.layout.lease(0), "elsewhere", 60.0)? else {
        panic!("a free lease is taken")
    };
    let outcome = process_shard(&job, 0, &mut options(KILLED, Limits::default(), false))?;
    assert_eq!(outcome, ShardOutcome::Busy("elsewhere".into()));
    assert!(!journal::set::exists(&job.layout, 0));
    held.release();
    Ok(())
}

/// Issue 32, item 4: another worker takes the lease over while an item converts (the item
/// worker script writes the new holder's lease, as a taker does once a holder was stopped
/// past its lease). The worker stops the item and the shard, says which lease it lost and to
/// whom, leaves the new holder's lease in place and writes no shard.
#[test]
fn a_worker_whose_lease_is_taken_over_stops_and_leaves_the_shard() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 2)?;
    let lease_file = job.layout.lease(0);
    let take_over = format!(
        "t=$(( $(date +%s) + 1000 )); \
         printf '{{\"owner\":\"newer\",\"host\":\"elsewhere\",\"pid\":1,\"heartbeat_at\":%s,\
         \"expires_at\":%s,\"acquired_at\":%s}}' $t $t $t > '{0}.x' && mv '{0}.x' '{0}'; \
         exec sleep 30",
        lease_file.display()
    );
    let mut opts = options(&take_over, Limits::default(), false);
    // A short lease: its heartbeat, which notices the takeover, beats every 0.1 s.
    opts.lease_ttl_s = 0.4;
    let outcome = process_shard(&job, 0, &mut opts)?;
    let ShardOutcome::LeaseLost(message) = outcome else {
        panic!("not stopped by the lost lease: {outcome:?}")
    };
    assert!(message.contains("lost its lease"), "{message}");
    assert!(
        message.contains(&lease_file.display().to_string()),
        "{message}"
    );
    assert!(message.contains("newer took it over"), "{message}");
    assert_eq!(
        lease::read(&lease_file).map(|l| l.owner),
        Some("newer".to_string()),
        "the new holder's lease is left in place"
    );
    assert!(!job.layout.shard_file(0).exists());
    assert!(!job.layout.completion(0).exists());
    Ok(())
}

/// A journal holding every item of the job's shard 0 as failed rows, written by `holder`.
fn full_journal(job: &Job, holder: &str) -> Result<Journal, Box<dyn std::error::Error>> {
    let mut j = Journal::create(
        &job.layout.holder_journal(0, holder),
        0,
        job.fingerprint(),
        JournalState::default(),
    )?;
    for item in &all_items(job) {
        let row = ShardRow::failed_item(
            item,
            64,
            ErrorClass::Geometry(sparcubes::ErrorClass::ParseError),
            holder.into(),
        );
        j.append(&Record::Done {
            row: Box::new(row),
            at: 1.0,
        })?;
    }
    Ok(j)
}

/// Issue 32, item 4: a writer that lost its lease while stopped, continued after the new
/// holder finished the shard, finds it finished and replaces neither its file nor its record.
#[test]
fn a_late_writer_never_replaces_a_finished_shard() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 2)?;
    process_shard(&job, 0, &mut options(KILLED, Limits::default(), false))?;
    let (file, record) = (job.layout.shard_file(0), job.layout.completion(0));
    let before = (std::fs::read(&file)?, std::fs::read(&record)?);
    let inode = std::os::unix::fs::MetadataExt::ino(&std::fs::metadata(&file)?);
    let late = full_journal(&job, "late")?;
    let no_fence = || Ok(());
    let committed = store::write::write_shard(&job, 0, &late, "late", 0.0, &no_fence)?;
    assert!(
        matches!(committed, store::commit::Committed::FinishedElsewhere(_)),
        "{committed:?}"
    );
    assert_eq!((std::fs::read(&file)?, std::fs::read(&record)?), before);
    assert_eq!(
        std::os::unix::fs::MetadataExt::ino(&std::fs::metadata(&file)?),
        inode
    );
    let leftovers: Vec<_> = std::fs::read_dir(job.layout.shards_dir())?
        .flatten()
        .map(|e| e.file_name())
        .filter(|n| n.to_string_lossy().starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    Ok(())
}

/// A shard file without its completion record (a writer stopped or killed between the two,
/// or `retry`) is not finished: the next writer puts its own in its place, with its record.
#[test]
fn a_shard_file_without_its_record_is_replaced_by_the_next_writer() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 2)?;
    std::fs::create_dir_all(job.layout.shards_dir())?;
    std::fs::write(job.layout.shard_file(0), b"left by a writer that stopped")?;
    let outcome = process_shard(&job, 0, &mut options(KILLED, Limits::default(), false))?;
    assert!(matches!(outcome, ShardOutcome::Done(_)), "{outcome:?}");
    let state =
        store::state::completion(&job.layout, 0, job.fingerprint(), store::state::Check::Full)?;
    assert!(
        matches!(state, store::state::Completion::Done(_)),
        "{state:?}"
    );
    assert_eq!(rows(&job)?.len(), 2);
    Ok(())
}

/// A failed row of item `index` of `job`, as holder `holder` would journal it.
fn done_record(job: &Job, index: usize, holder: &str) -> Record {
    let row = ShardRow::failed_item(
        &all_items(job)[index],
        64,
        ErrorClass::Geometry(sparcubes::ErrorClass::ParseError),
        holder.into(),
    );
    Record::Done {
        row: Box::new(row),
        at: 1.0,
    }
}

/// Issue 46: rows go into the shard file as their items finish, in item order whatever order
/// they finish in, so a shard streamed from items finishing out of order is the very file
/// written from a finished journal at the end; a stream dropped before its commit (a stop, a
/// lost lease) leaves no temporary file.
#[test]
fn a_shard_streamed_as_items_finish_out_of_order_is_the_file_written_at_the_end() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 5)?;
    std::fs::create_dir_all(job.layout.shards_dir())?;
    let no_fence = || Ok(());
    let in_order = full_journal(&job, "w")?;
    let at_the_end = store::write::write_shard(&job, 0, &in_order, "a", 0.0, &no_fence)?;
    let expected = std::fs::read(job.layout.shard_file(0))?;
    drop(in_order);
    journal::set::remove_all(&job.layout, 0)?;
    std::fs::remove_file(job.layout.shard_file(0))?;
    std::fs::remove_file(job.layout.completion(0))?;

    let mut streamed = Journal::create(
        &job.layout.holder_journal(0, "w"),
        0,
        job.fingerprint(),
        JournalState::default(),
    )?;
    let mut stream = store::write::ShardStream::create(&job, 0, "b")?;
    for index in [3, 1, 4, 0, 2] {
        streamed.append(&done_record(&job, index, "w"))?;
        stream.catch_up(&streamed)?;
    }
    let committed = stream.finish(&job, 0, 0.0, &no_fence)?;
    assert_eq!(std::fs::read(job.layout.shard_file(0))?, expected);
    let (store::commit::Committed::Done(a), store::commit::Committed::Done(b)) =
        (at_the_end, committed)
    else {
        panic!("both commits should have put their shard in place");
    };
    assert_eq!((a.sha256, a.content_digest), (b.sha256, b.content_digest));

    let mut unfinished = store::write::ShardStream::create(&job, 0, "c")?;
    unfinished.catch_up(&streamed)?;
    let tmp = job.layout.shard_tmp(0, "c");
    assert!(tmp.exists());
    drop(unfinished);
    assert!(!tmp.exists(), "{} left behind", tmp.display());
    Ok(())
}

/// A stream cannot commit a shard with an item not finished: it says which.
#[test]
fn a_stream_refuses_to_commit_a_shard_with_an_unfinished_item() -> TestResult {
    let dir = tempfile::tempdir()?;
    let job = job(dir.path(), 3)?;
    std::fs::create_dir_all(job.layout.shards_dir())?;
    let mut partial = Journal::create(
        &job.layout.holder_journal(0, "w"),
        0,
        job.fingerprint(),
        JournalState::default(),
    )?;
    partial.append(&done_record(&job, 0, "w"))?;
    partial.append(&done_record(&job, 2, "w"))?;
    let mut stream = store::write::ShardStream::create(&job, 0, "w")?;
    stream.catch_up(&partial)?;
    let no_fence = || Ok(());
    let err = match stream.finish(&job, 0, 0.0, &no_fence) {
        Ok(c) => panic!("committed with item 1 missing: {c:?}"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("item 1 of shard 0 is not finished"), "{err}");
    assert!(!job.layout.shard_file(0).exists());
    assert!(!job.layout.shard_tmp(0, "w").exists());
    Ok(())
}
