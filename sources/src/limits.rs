//! How long and how much a fetch may take: time-outs, retries, the byte cap. Defaults suit a
//! data-centre link; `SPARC3D_FETCH_*` environment variables override them at run time (they
//! are not part of a job's fingerprint, like `--item-timeout`).

use std::time::Duration;

/// The limits of one fetch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FetchLimits {
    /// Time to open a connection (TCP and TLS) before the attempt fails and is retried.
    pub connect_timeout: Duration,
    /// Longest wait for the next bytes of a response (headers or body) before the attempt
    /// fails and is retried; resets whenever bytes arrive.
    pub read_timeout: Duration,
    /// Retries after a failed attempt (connection errors, time-outs, 429, 5xx), with
    /// exponential backoff from [`FetchLimits::initial_backoff`] up to
    /// [`FetchLimits::max_backoff`].
    pub retries: usize,
    /// The first backoff.
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
            retries: 5,
            initial_backoff: Duration::from_millis(200),
            max_backoff: Duration::from_secs(15),
            max_bytes: 4 << 30,
        }
    }
}

/// The environment variables read by [`FetchLimits::from_env`], with what each sets.
pub const ENV_VARS: [(&str, &str); 4] = [
    (
        "SPARC3D_FETCH_CONNECT_TIMEOUT",
        "connect time-out in seconds (default 10)",
    ),
    (
        "SPARC3D_FETCH_READ_TIMEOUT",
        "read time-out in seconds (default 30)",
    ),
    (
        "SPARC3D_FETCH_RETRIES",
        "retries after a failed attempt (default 5)",
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
        if let Some(n) = read(ENV_VARS[2].0)? {
            limits.retries = n as usize;
        }
        if let Some(n) = read(ENV_VARS[3].0)? {
            limits.max_bytes = n as u64;
        }
        Ok(limits)
    }
}
