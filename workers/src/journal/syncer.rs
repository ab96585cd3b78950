//! The background fsync of a journal file: a thread that fsyncs whenever asked, coalescing
//! requests made during a flush (group commit), so the disk flush is off the per-item path.

use std::fs::File;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;

/// Progress of the background fsyncs of one file.
#[derive(Debug, Default)]
struct SyncState {
    /// Flushes asked for so far.
    requested: u64,
    /// Flushes done (a flush started after request k covers every request up to k).
    synced: u64,
    /// The first failed flush, until reported.
    error: Option<std::io::Error>,
    /// Set when the journal closes: finish the pending flush, then stop.
    closing: bool,
}

/// A thread that fsyncs a file whenever asked, coalescing requests made during a flush.
#[derive(Debug)]
pub(super) struct Syncer {
    shared: Arc<(Mutex<SyncState>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl Syncer {
    pub(super) fn start(file: File) -> Self {
        let shared = Arc::new((Mutex::new(SyncState::default()), Condvar::new()));
        let worker = Arc::clone(&shared);
        let thread = std::thread::spawn(move || {
            let (lock, cvar) = &*worker;
            let Ok(mut st) = lock.lock() else { return };
            loop {
                while st.synced >= st.requested && !st.closing {
                    st = match cvar.wait(st) {
                        Ok(st) => st,
                        Err(_) => return,
                    };
                }
                if st.synced >= st.requested {
                    return;
                }
                let target = st.requested;
                drop(st);
                let result = file.sync_data();
                st = match lock.lock() {
                    Ok(st) => st,
                    Err(_) => return,
                };
                st.synced = target;
                if let Err(e) = result {
                    st.error.get_or_insert(e);
                }
                cvar.notify_all();
            }
        });
        Self {
            shared,
            thread: Some(thread),
        }
    }

    /// Asks for a flush of everything written so far; returns at once.
    pub(super) fn request(&self) {
        let (lock, cvar) = &*self.shared;
        if let Ok(mut st) = lock.lock() {
            st.requested += 1;
            cvar.notify_all();
        }
    }

    /// The error of a failed flush, if one failed since the last call.
    pub(super) fn take_error(&self) -> Option<std::io::Error> {
        let (lock, _) = &*self.shared;
        match lock.lock() {
            Ok(mut st) => st.error.take(),
            Err(_) => Some(std::io::Error::other("journal sync thread panicked")),
        }
    }

    /// Flushes everything written so far and waits for it.
    pub(super) fn flush(&self) -> std::io::Result<()> {
        let (lock, cvar) = &*self.shared;
        let poisoned = || std::io::Error::other("journal sync thread panicked");
        let mut st = lock.lock().map_err(|_| poisoned())?;
        st.requested += 1;
        let target = st.requested;
        cvar.notify_all();
        while st.synced < target {
            st = cvar.wait(st).map_err(|_| poisoned())?;
        }
        st.error.take().map_or(Ok(()), Err)
    }
}

impl Syncer {
    /// Stops without flushing what is still asked for and without waiting for the flush
    /// running (it finishes in the background).
    pub(super) fn abandon(mut self) {
        let (lock, cvar) = &*self.shared;
        if let Ok(mut st) = lock.lock() {
            st.requested = st.synced;
            st.closing = true;
            cvar.notify_all();
        }
        // Dropping the handle detaches the thread instead of joining it.
        self.thread = None;
    }
}

impl Drop for Syncer {
    fn drop(&mut self) {
        let (lock, cvar) = &*self.shared;
        if let Ok(mut st) = lock.lock() {
            st.closing = true;
            cvar.notify_all();
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
