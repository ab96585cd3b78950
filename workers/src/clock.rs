//! The wall clock, for times in records and unique names.

/// Seconds since the Unix epoch.
pub fn now() -> f64 {
    since_epoch().as_secs_f64()
}

/// Time since the Unix epoch (zero on a clock set before it), for times and unique names.
pub fn since_epoch() -> std::time::Duration {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
}
