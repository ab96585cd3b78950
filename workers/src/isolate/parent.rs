//! Tying a process's life to its parent's: a worker started by an orchestrator (and an item
//! worker started by its supervisor) must not outlive it, holding a lease or converting an item
//! for nobody.

/// Asks the kernel to send `signal` to this process when its parent dies (Linux
/// `PR_SET_PDEATHSIG`), and exits at once with status 3 if the parent (`parent_pid`, 0 for
/// unknown) is already gone, which happens when it died before this call.
pub fn die_with_parent(parent_pid: u32, signal: i32) {
    #[cfg(target_os = "linux")]
    // SAFETY: prctl with PR_SET_PDEATHSIG takes a signal number.
    unsafe {
        libc::prctl(libc::PR_SET_PDEATHSIG, signal);
    }
    // SAFETY: getppid has no preconditions.
    if parent_pid != 0 && unsafe { libc::getppid() } as u32 != parent_pid {
        std::process::exit(3);
    }
}
