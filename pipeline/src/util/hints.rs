//! The lines that point a user to the next command: where a job's failures are explained, and
//! what to run once a job is done. Shared by `run`, `status` and `ls`.

use std::path::Path;

/// "N items failed: `sparc3d failures JOB` says why …", or `None` when nothing failed.
pub fn failures(job: &Path, failed: u64) -> Option<String> {
    let job = job.display();
    (failed > 0).then(|| {
        format!(
            "{failed} item{} failed: `sparc3d failures {job}` says why; `sparc3d retry {job}` \
             queues them again",
            if failed == 1 { "" } else { "s" }
        )
    })
}

/// Where a finished job's shards are and the commands to look at it, one per line.
pub fn next_steps(job: &Path, shards: u64) -> String {
    let shards_dir = sparc3d_schema::JobLayout::new(job).shards_dir();
    let j = job.display();
    let commands = [
        (format!("sparc3d status {j}"), "progress, rate, errors"),
        (
            format!("sparc3d ls {j}"),
            "items with their ids, status and source",
        ),
        (
            format!("sparc3d inspect {j}"),
            "rows, bytes per column, content digest",
        ),
        (
            format!("sparc3d show {j} --id ID -o item.ply"),
            "one item's mesh (ID: an id prefix or the file name)",
        ),
        (
            format!("sparc3d report {j} -o report.html"),
            "one page: histograms, previews, failures",
        ),
    ];
    let width = commands.iter().map(|(c, _)| c.len()).max().unwrap_or(0);
    let mut text = format!(
        "shards: {} ({shards} Parquet file{}; docs/FORMAT.md says how to read them)\nnext:",
        shards_dir.display(),
        if shards == 1 { "" } else { "s" }
    );
    for (command, what) in commands {
        text.push_str(&format!("\n  {command:<width$}  {what}"));
    }
    text
}
