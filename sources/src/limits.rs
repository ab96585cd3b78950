//! How long and how much a fetch may take: time-outs, retries, the byte cap. Defaults suit a
//! data-centre link; `SPARC3D_FETCH_*` environment variables override them at run time (they
//! are not part of a job's fingerprint, like `--item-timeout`).

use std::time::{Duration, Instant};

/// The limits of one fetch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FetchLimits {
    /// Time to open a connection (TCP and TLS) before the attempt fails and is retried.
    pub connect_timeout: Duration,
    /// Longest wait for the next bytes of a response (headers or body) before the attempt
    /// fails and is retried; resets whenever bytes arrive.
    pub read_timeout: Duration,
    /// The most retries after a failed attempt (connection errors, time-outs, 429, 5xx); the
    /// default, 100, is more than [`FetchLimits::retry_for`] has room for, so the time ends
    /// them.
    pub retries: usize,
    /// How long after its first attempt a failing request is still retried: an outage of the
    /// store or server shorter than this fails nothing. The default, 60 s, is a bucket lease's
    /// default time to live (`sparc3d work --lease-ttl`), so a blip that a lease outlives
    /// fails no item and no upload either.
    pub retry_for: Duration,
    /// The first backoff; each next one doubles, up to [`FetchLimits::max_backoff`].
    pub initial_backoff: Duration,
    /// The longest backoff.
    pub max_backoff: Duration,
    /// The most bytes fetched for one object: a larger object is refused from its size
    /// (Content-Length, the listing) before its body is read, and a body that runs past it
    /// is cut there.
    pub max_bytes: u64,
}

impl Default for FetchLimits {
    fn default() -> Self {
        Self {
            connect_timeout: Duration::from_secs(10),
            read_timeout: Duration::from_secs(30),
            retries: 100,
            retry_for: Duration::from_secs(60),
            initial_backoff: Duration::from_millis(200),
            max_backoff: Duration::from_secs(15),
            max_bytes: 4 << 30,
        }
    }
}

/// The environment variables read by [`FetchLimits::from_env`], with what each sets.
pub const ENV_VARS: [(&str, &str); 5] = [
    (
        "SPARC3D_FETCH_CONNECT_TIMEOUT",
        "connect time-out in seconds (default 10)",
    ),
    (
        "SPARC3D_FETCH_READ_TIMEOUT",
        "read time-out in seconds (default 30)",
    ),
    (
        "SPARC3D_FETCH_RETRY_FOR",
        "seconds a failing request is retried for (default 60)",
    ),
    (
        "SPARC3D_FETCH_RETRIES",
        "the most retries of one request (default 100: SPARC3D_FETCH_RETRY_FOR ends them first)",
    ),
    (
        "SPARC3D_FETCH_MAX_BYTES",
        "byte cap per object (default 4294967296)",
    ),
];

impl FetchLimits {
    /// The defaults with `max_bytes`, overridden by the `SPARC3D_FETCH_*` variables that are
    /// set; a value that is not a number is an error naming the variable.
    pub fn from_env(max_bytes: u64) -> Result<Self, String> {
        let mut limits = Self {
            max_bytes,
            ..Self::default()
        };
        let read = |name: &str| -> Result<Option<f64>, String> {
            match std::env::var(name) {
                Err(_) => Ok(None),
                Ok(v) => match v.trim().parse::<f64>() {
                    Ok(x) if x.is_finite() && x >= 0.0 => Ok(Some(x)),
                    _ => Err(format!("{name}={v:?} is not a non-negative number")),
                },
            }
        };
        if let Some(s) = read(ENV_VARS[0].0)? {
            limits.connect_timeout = Duration::from_secs_f64(s);
        }
        if let Some(s) = read(ENV_VARS[1].0)? {
            limits.read_timeout = Duration::from_secs_f64(s);
        }
        if let Some(s) = read(ENV_VARS[2].0)? {
            limits.retry_for = Duration::from_secs_f64(s);
        }
        if let Some(n) = read(ENV_VARS[3].0)? {
            limits.retries = n as usize;
        }
        if let Some(n) = read(ENV_VARS[4].0)? {
            limits.max_bytes = n as u64;
        }
        Ok(limits)
    }
}

/// The waits between the attempts of one request: [`FetchLimits::initial_backoff`] doubling up
/// to [`FetchLimits::max_backoff`], while fewer than [`FetchLimits::retries`] retries were made
/// and less than [`FetchLimits::retry_for`] has passed since the first attempt.
#[derive(Debug)]
pub struct Backoff {
    limits: FetchLimits,
    started: Instant,
    retries: usize,
    next: Duration,
}

impl Backoff {
    /// The waits of a request whose first attempt starts now.
    pub fn new(limits: &FetchLimits) -> Self {
        Self {
            limits: *limits,
            started: Instant::now(),
            retries: 0,
            next: limits.initial_backoff,
        }
    }

    /// The wait before the next retry, or `None` when no retry is left.
    pub fn next_wait(&mut self) -> Option<Duration> {
        if self.retries >= self.limits.retries || self.started.elapsed() >= self.limits.retry_for {
            return None;
        }
        self.retries += 1;
        let wait = self.next;
        self.next = (self.next * 2).min(self.limits.max_backoff);
        Some(wait)
    }

    /// The retries made so far and the seconds since the first attempt, for messages.
    pub fn said(&self) -> String {
        format!(
            "after {} retries in {:.1} s",
            self.retries,
            self.started.elapsed().as_secs_f64()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_to_its_longest_and_ends_by_count_or_time() {
        let limits = FetchLimits {
            retries: 8,
            ..FetchLimits::default()
        };
        let mut b = Backoff::new(&limits);
        let waits: Vec<u128> = std::iter::from_fn(|| b.next_wait())
            .map(|d| d.as_millis())
            .collect();
        assert_eq!(waits, [200, 400, 800, 1600, 3200, 6400, 12800, 15000]);
        let by_time = FetchLimits {
            retry_for: Duration::ZERO,
            ..FetchLimits::default()
        };
        assert_eq!(Backoff::new(&by_time).next_wait(), None);
        // By default the time ends the retries: 100 waits are more than 60 s.
        let mut b = Backoff::new(&FetchLimits::default());
        let total: Duration = std::iter::from_fn(|| b.next_wait()).sum();
        assert!(total > FetchLimits::default().retry_for, "{total:?}");
    }
}
