//! `--item-timeout`, `--item-memory`, `--max-crash-retries` (and the hidden `--lease-ttl`):
//! the per-item limits of a run that override the job's (`work`, `run`, `submit`).

use crate::util::units::{format_seconds, format_size, parse_duration, parse_size, with_default};
use sparc3d_schema::Limits;

/// Per-item limits given on the command line (override the job's for this run).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct LimitArgs {
    /// Time limit per item (e.g. 90, 30s, 10m); default: the job's `limits.item_timeout_s`.
    #[arg(long, value_parser = parse_duration, help = with_default(
        "Time limit per item (e.g. 90, 30s, 10m)",
        format!("the job's limits.item_timeout_s, {} unless its config sets another",
            format_seconds(Limits::default().item_timeout_s)),
    ))]
    pub item_timeout: Option<f64>,
    /// Memory (address-space) limit per item (e.g. 8G; 0 for none); default: the job's
    /// `limits.item_memory_bytes`.
    #[arg(long, value_parser = parse_size, help = with_default(
        "Memory (address-space) limit per item (e.g. 8G; 0 for none)",
        format!("the job's limits.item_memory_bytes, {} unless its config sets another",
            format_size(Limits::default().item_memory_bytes)),
    ))]
    pub item_memory: Option<u64>,
    /// Retries of an item whose process crashed; default: the job's `limits.max_crash_retries`.
    #[arg(long, help = with_default(
        "Retries of an item whose process crashed",
        format!("the job's limits.max_crash_retries, {} unless its config sets another",
            Limits::default().max_crash_retries),
    ))]
    pub max_crash_retries: Option<u32>,
    /// Seconds a shard lease lives without a heartbeat.
    #[arg(long, default_value_t = 60.0, hide = true)]
    pub lease_ttl: f64,
}

impl LimitArgs {
    /// The job's limits overridden by the flags.
    pub fn apply(&self, mut l: Limits) -> Limits {
        if let Some(t) = self.item_timeout {
            l.item_timeout_s = t;
        }
        if let Some(m) = self.item_memory {
            l.item_memory_bytes = m;
        }
        if let Some(r) = self.max_crash_retries {
            l.max_crash_retries = r;
        }
        l
    }

    /// The flags as command-line arguments, to pass on to `work`.
    pub fn to_args(&self) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(t) = self.item_timeout {
            a.extend(["--item-timeout".into(), t.to_string()]);
        }
        if let Some(m) = self.item_memory {
            a.extend(["--item-memory".into(), m.to_string()]);
        }
        if let Some(r) = self.max_crash_retries {
            a.extend(["--max-crash-retries".into(), r.to_string()]);
        }
        a.extend(["--lease-ttl".into(), self.lease_ttl.to_string()]);
        a
    }
}
