//! Wall and CPU time for the benchmark examples.

use std::time::Instant;

/// CPU seconds of this process so far (every thread).
pub fn cpu() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec for clock_gettime to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) };
    t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
}

/// Wall and CPU seconds since it started.
pub struct Clock(Instant, f64);

impl Clock {
    /// Starts counting now.
    pub fn start() -> Self {
        Clock(Instant::now(), cpu())
    }

    /// "W s (C s CPU)" since the start, with `decimals` digits.
    pub fn secs(&self, decimals: usize) -> String {
        format!(
            "{:.*} s ({:.*} s CPU)",
            decimals,
            self.0.elapsed().as_secs_f64(),
            decimals,
            cpu() - self.1
        )
    }
}
