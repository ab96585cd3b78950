//! `sparc3d failures JOB [--json]`: every failed item with its class and message, one line
//! each: class, id, source and the whole message, separated by tabs and escaped
//! (`sparc3d_manifests::tsv`), then the item's provenance columns as `name=value` fields
//! (`--json`: a `manifest` object).

use anyhow::Result;
use serde::Serialize;
use sparc3d_manifests::tsv;
use sparc3d_schema::ItemStatus;
use sparc3d_workers::store::read::shard_rows;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d failures`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// Only this error class.
    #[arg(long)]
    pub class: Option<String>,
    /// Print JSON lines.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Failure {
    shard: u64,
    id: String,
    uri: String,
    error_class: String,
    error_message: String,
    attempts: u32,
    stderr_tail: Option<String>,
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    manifest: BTreeMap<String, String>,
}

/// Runs `sparc3d failures`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    let job = crate::job::setup::open_read_only(&args.job)?;
    let mut n = 0;
    let mut out = std::io::stdout().lock();
    for shard in 0..job.file.shards {
        for row in shard_rows(&job, shard, sparc3d_workers::store::state::Check::Quick)? {
            if row.status != ItemStatus::Failed {
                continue;
            }
            let class = row.error_class.map(|c| c.as_str()).unwrap_or("unknown");
            if args.class.as_deref().is_some_and(|c| c != class) {
                continue;
            }
            n += 1;
            let f = Failure {
                shard,
                id: row.id,
                uri: row.uri,
                error_class: class.to_string(),
                error_message: row.error_message.unwrap_or_default(),
                attempts: row.attempts,
                stderr_tail: row.stderr_tail,
                manifest: job
                    .item(row.item_index)?
                    .map(|item| item.record.extra)
                    .unwrap_or_default(),
            };
            let line = if args.json {
                serde_json::to_string(&f)?
            } else {
                let (id, uri) = (tsv::field(&f.id), tsv::field(&f.uri));
                let msg = tsv::field(&f.error_message);
                let provenance = tsv::provenance(&f.manifest);
                format!("{}\t{id}\t{uri}\t{msg}{provenance}", f.error_class)
            };
            if writeln!(out, "{line}").is_err() {
                return Ok(ExitCode::SUCCESS); // the reader went away (e.g. `| head`)
            }
        }
    }
    if !args.json {
        eprintln!("{n} failed items");
    }
    Ok(ExitCode::SUCCESS)
}
