//! The item worker process: reads the job config and then one item per line on stdin, runs
//! [`crate::item::row::convert_item`] on each in a thread with a large stack, catches panics,
//! and answers each item with a `Done` frame. A stack overflow, an allocation failure under
//! its memory limit or a signal kills the process; the supervisor attributes that to the item.

use crate::journal::record::{self, Record};
use sparc3d_schema::{ErrorClass, FrozenItem, JobConfig, ShardRow};
use std::io::{BufRead, Write};
use std::os::fd::FromRawFd;
use std::sync::Mutex;

/// Stack size of the thread converting an item.
const ITEM_STACK: usize = 64 << 20;

static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Options of the item worker process (from its command line).
#[derive(Debug, Clone, Copy, Default)]
pub struct ChildOptions {
    /// Address-space limit in bytes (0: none).
    pub memory_bytes: u64,
    /// The supervisor's pid: the child exits when it is gone.
    pub parent_pid: u32,
}

/// Takes fd 1 for the protocol and points fd 1 at stderr, so stray prints cannot corrupt it.
fn protocol_stdout() -> std::io::Result<std::fs::File> {
    // SAFETY: dup/dup2 on the process's own standard descriptors.
    unsafe {
        let fd = libc::dup(1);
        if fd < 0 || libc::dup2(2, 1) < 0 {
            return Err(std::io::Error::last_os_error());
        }
        Ok(std::fs::File::from_raw_fd(fd))
    }
}

fn install_panic_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let msg = match info.payload().downcast_ref::<&str>() {
            Some(s) => s.to_string(),
            None => info
                .payload()
                .downcast_ref::<String>()
                .cloned()
                .unwrap_or_else(|| "panic".into()),
        };
        let at = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        if let Ok(mut g) = LAST_PANIC.lock() {
            *g = Some(format!("panicked{at}: {msg}"));
        }
        default(info);
    }));
}

fn run_one(item: &FrozenItem, config: &JobConfig, memory_bytes: u64) -> ShardRow {
    let (it, cfg) = (item.clone(), config.clone());
    let handle = std::thread::Builder::new()
        .name(format!("item-{}", item.index))
        .stack_size(ITEM_STACK)
        .spawn(move || crate::item::row::convert_item(&it, &cfg, memory_bytes));
    let failed = |class, message: String| {
        ShardRow::failed(
            item.index,
            &item.record.id,
            &item.record.uri,
            config.params.resolution,
            class,
            message,
        )
    };
    match handle {
        Ok(h) => match h.join() {
            Ok(row) => row,
            Err(_) => {
                let msg = LAST_PANIC
                    .lock()
                    .ok()
                    .and_then(|mut g| g.take())
                    .unwrap_or_else(|| "panicked".into());
                failed(ErrorClass::Panic, msg)
            }
        },
        Err(e) => failed(
            ErrorClass::OutOfMemory,
            format!(
                "the item memory limit of {} (--item-memory) is too small to start the \
                 conversion thread with its {}M stack ({e}); raise it",
                crate::isolate::supervisor::describe_memory_limit(memory_bytes),
                ITEM_STACK >> 20
            ),
        ),
    }
}

/// Runs the item worker loop until stdin closes; returns the process exit code.
pub fn main(opts: ChildOptions) -> i32 {
    crate::isolate::parent::die_with_parent(opts.parent_pid, libc::SIGKILL);
    let mut out = match protocol_stdout() {
        Ok(f) => f,
        Err(e) => {
            eprintln!("item worker: cannot set up its output: {e}");
            return 2;
        }
    };
    if let Err(e) = crate::isolate::process::set_memory_limit(opts.memory_bytes) {
        eprintln!("item worker: cannot set the memory limit: {e}");
        return 2;
    }
    install_panic_hook();
    let stdin = std::io::stdin();
    let mut lines = stdin.lock().lines();
    let config: JobConfig = match lines.next() {
        Some(Ok(l)) => match serde_json::from_str(&l) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("item worker: bad config line: {e}");
                return 2;
            }
        },
        _ => return 0,
    };
    for line in lines {
        let Ok(line) = line else { return 0 };
        let item: FrozenItem = match serde_json::from_str(&line) {
            Ok(i) => i,
            Err(e) => {
                eprintln!("item worker: bad item line: {e}");
                return 2;
            }
        };
        let row = run_one(&item, &config, opts.memory_bytes);
        let bytes = match record::encode(&Record::Done {
            row: Box::new(row),
            at: crate::clock::now(),
        }) {
            Ok(b) => b,
            Err(e) => {
                eprintln!("item worker: cannot encode item {}: {e}", item.index);
                return 2;
            }
        };
        if out.write_all(&bytes).and_then(|_| out.flush()).is_err() {
            return 0; // the supervisor is gone
        }
    }
    0
}
