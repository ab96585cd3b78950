//! `sparc3d ls JOB [--failed] [--json]`: every item of a job in manifest order with its id,
//! status (`ok`, `failed:CLASS`, `skipped`, `pending`, or `damaged` when its finished shard no longer
//! matches its record) and source file: where the ids that `show`/`preview --id` take come
//! from. One line per item, fields separated by tabs and escaped (`sparc3d_manifests::tsv`),
//! then the item's provenance columns as `name=value` fields (`--json`: a `manifest` object).
//! `--where FILTER` lists only the items whose row passes (`crate::rows::row_filter`; a pending item
//! has only its id, uri, index and provenance).
//! `--one-per-group` leaves out every near-duplicate but its group's representative
//! (`sparc3d dedup`). The summary on stderr counts the items listed, and says how many each
//! option left out.

use crate::rows::row_filter::RowFilter;
use crate::util::hints;
use anyhow::Result;
use serde::Serialize;
use sparc3d_manifests::tsv;
use sparc3d_schema::ItemStatus;
use sparc3d_workers::store::read::shard_rows;
use sparc3d_workers::store::state::Check;
use sparc3d_workers::Job;
use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d ls`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// Only the failed items.
    #[arg(long)]
    pub failed: bool,
    /// Only the items whose row passes this filter, in `init --where`'s language over the
    /// shards' columns: `input_faces <= 1000000 and license in (cc0, cc-by)`.
    #[arg(long = "where", value_name = "FILTER")]
    pub filter: Option<String>,
    /// Print JSON lines (index, shard, id, status, error_class, uri, and `manifest`: the
    /// provenance columns, when the manifest had any).
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub dedup: super::dedup::OnePerGroup,
}

/// One listed item.
#[derive(Serialize)]
struct Listed<'a> {
    index: u64,
    shard: u64,
    id: &'a str,
    status: &'static str,
    error_class: Option<&'static str>,
    uri: &'a str,
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    manifest: &'a BTreeMap<String, String>,
}

/// A finished item's status, error class, and whether its row passes `--where`.
type Finished = (ItemStatus, Option<&'static str>, bool);

/// Statuses (and error classes) of a shard's finished items by manifest position, each with
/// whether `filter` keeps it; `None` when the shard cannot be read (damaged), said on stderr.
fn shard_statuses(
    job: &Job,
    shard: u64,
    filter: Option<&RowFilter>,
) -> Result<Option<HashMap<u64, Finished>>> {
    let rows = match shard_rows(job, shard, Check::Quick) {
        Ok(rows) => rows,
        Err(e) => {
            eprintln!("shard {shard}: {e:#}");
            return Ok(None);
        }
    };
    let mut out = HashMap::new();
    for mut r in rows {
        let item = job.item(r.item_index)?;
        let keep = match filter {
            Some(f) => f.keeps(&mut r, item.as_ref())?,
            None => true,
        };
        let class = r.error_class.map(|c| c.as_str());
        out.insert(r.item_index, (r.status, class, keep));
    }
    Ok(Some(out))
}

/// What `ls` says of `item`: its status, error class, and whether it passes `filter` (an item
/// without a row, pending or in a damaged shard, by what its manifest says of it).
fn listed_status(
    statuses: Option<&HashMap<u64, Finished>>,
    item: &sparc3d_schema::FrozenItem,
    filter: Option<&RowFilter>,
) -> (&'static str, Option<&'static str>, bool) {
    let pending_kept = || filter.is_none_or(|f| f.keeps_pending(item));
    match statuses {
        None => ("damaged", None, pending_kept()),
        Some(s) => match s.get(&item.index) {
            Some((ItemStatus::Ok, _, k)) => ("ok", None, *k),
            Some((ItemStatus::Skipped, _, k)) => ("skipped", None, *k),
            Some((ItemStatus::Failed, class, k)) => {
                ("failed", Some(class.unwrap_or("unknown")), *k)
            }
            None => ("pending", None, pending_kept()),
        },
    }
}

/// Items `ls` leaves out of its listing and its summary's counts.
#[derive(Debug, Default)]
struct LeftOut {
    /// By `--where`.
    by_filter: u64,
    /// By `--one-per-group` (near-duplicates of a group's representative), among the items
    /// `--where` keeps: an item both leave out counts once, under `by_filter`.
    by_group: u64,
}

/// Runs `sparc3d ls`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    // Messages name the job as given (a URL), not its local view.
    let named = args.job.clone();
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    let job = crate::job::setup::open_read_only(&args.job)?;
    let filter = RowFilter::optional(&job, args.filter.as_deref())?;
    let dropped = args.dedup.dropped(&job, &named, filter.as_ref())?;
    let mut left_out = LeftOut::default();
    let mut out = std::io::stdout().lock();
    let mut statuses = None;
    let mut loaded = None;
    let mut counts: HashMap<&'static str, u64> = HashMap::new();
    for item in job.items() {
        let item = item?;
        if loaded != Some(item.shard) {
            statuses = shard_statuses(&job, item.shard, filter.as_ref())?;
            loaded = Some(item.shard);
        }
        let (status, class, keep) = listed_status(statuses.as_ref(), &item, filter.as_ref());
        if !keep {
            left_out.by_filter += 1;
            continue;
        }
        if dropped.contains(&item.record.id) {
            left_out.by_group += 1;
            continue;
        }
        *counts.entry(status).or_default() += 1;
        if args.failed && status != "failed" {
            continue;
        }
        let listed = Listed {
            index: item.index,
            shard: item.shard,
            id: &item.record.id,
            status,
            error_class: class,
            uri: &item.record.uri,
            manifest: &item.record.extra,
        };
        let line = if args.json {
            serde_json::to_string(&listed)?
        } else {
            let status = match class {
                Some(c) => format!("{status}:{c}"),
                None => status.to_string(),
            };
            let (id, uri) = (tsv::field(listed.id), tsv::field(listed.uri));
            let provenance = tsv::provenance(listed.manifest);
            format!("{id}\t{status}\t{uri}{provenance}")
        };
        if writeln!(out, "{line}").is_err() {
            return Ok(ExitCode::SUCCESS); // the reader went away (e.g. `| head`)
        }
    }
    if let Some(f) = &filter {
        eprintln!("--where {}: {} items left out", f.text, left_out.by_filter);
    }
    if args.dedup.one_per_group {
        eprintln!(
            "--one-per-group: {} near-duplicates left out",
            left_out.by_group
        );
    }
    let n = |k: &str| counts.get(k).copied().unwrap_or(0);
    eprintln!(
        "{} items: {} ok, {} failed, {} pending{}",
        job.file.items - left_out.by_filter - left_out.by_group,
        n("ok"),
        n("failed"),
        n("pending"),
        if n("damaged") > 0 {
            format!(", {} in damaged shards", n("damaged"))
        } else {
            String::new()
        }
    );
    if let Some(hint) = hints::failures(&named, n("failed")) {
        eprintln!("{hint}");
    }
    Ok(ExitCode::SUCCESS)
}
