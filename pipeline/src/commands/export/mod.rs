//! `sparc3d export JOB --format CONSUMER --out DIR [--ids …] [--frame …]`: writes the ok items
//! of a job in a consumer's own on-disk layout (docs/FORMAT.md, "Exports"), through
//! `sparc3d_formats`, which holds each consumer's recipe and writes the export folder
//! (`sparc3d_formats::export`): built beside `--out` and moved into place at the end, so
//! `--out` is never half written, with `.sparc3d-export.json` saying which job, consumer,
//! frame and items it holds. Here: the command line, what the job lacks for the consumer,
//! which items (`--ids`, `--where FILTER` over the rows, `crate::rows::row_filter`,
//! `--one-per-group`), and the summary; `items.rs` reads the rows and makes their files.

mod items;

use crate::rows::item_lookup;
use crate::rows::row_filter::RowFilter;
use anyhow::{Context, Result};
use clap::builder::TypedValueParser;
use items::Chosen;
use sparc3d_formats::export::{debris, Record, Staging};
use sparc3d_formats::{Consumer, Frame};
use sparc3d_workers::Job;
use std::collections::BTreeSet;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// The consumer whose layout to write (docs/FORMAT.md, "Exports", has the table).
    #[arg(long, value_parser = consumer_parser())]
    pub format: Consumer,
    /// Output folder: created, or replaced whole when it holds an earlier export.
    #[arg(long)]
    pub out: PathBuf,
    /// Only these items (comma-separated or repeated), each named as `--id` elsewhere: its id,
    /// a unique prefix of it, or its source file (path or file name); default: every ok item.
    #[arg(long, value_delimiter = ',')]
    pub ids: Vec<String>,
    /// Frame of the points: the consumer's own by default (`consumer` for the grid layouts,
    /// `normalized` for vecset-npz); `source` and `normalized` where the layout allows them.
    #[arg(long, value_parser = frame_parser())]
    pub frame: Option<Frame>,
    /// Only the items whose row passes this filter, in `init --where`'s language over the
    /// shards' columns: `input_faces <= 1000000 and license in (cc0, cc-by)`.
    #[arg(long = "where", value_name = "FILTER")]
    pub filter: Option<String>,
    #[command(flatten)]
    pub dedup: super::dedup::OnePerGroup,
}

/// `--format`'s parser: the consumers' names, each with its `--help` line.
fn consumer_parser() -> impl clap::builder::TypedValueParser<Value = Consumer> {
    let values = Consumer::ALL
        .iter()
        .map(|c| clap::builder::PossibleValue::new(c.name()).help(c.about()));
    clap::builder::PossibleValuesParser::new(values).try_map(|name| {
        Consumer::from_name(&name).ok_or_else(|| format!("no consumer named {name}"))
    })
}

/// `--frame`'s parser.
fn frame_parser() -> impl clap::builder::TypedValueParser<Value = Frame> {
    clap::builder::PossibleValuesParser::new(Frame::ALL.map(|f| f.name())).try_map(|name| {
        Frame::ALL
            .into_iter()
            .find(|f| f.name() == name)
            .ok_or_else(|| format!("no frame named {name}"))
    })
}

/// Takes `--one-per-group`'s `dropped` ids out of the `wanted` ones (every item when none
/// were named) and says how many it took; an error when nothing is left.
fn leave_out_near_duplicates(
    job: &Job,
    wanted: &mut BTreeSet<String>,
    dropped: &std::collections::HashSet<String>,
) -> Result<()> {
    if dropped.is_empty() {
        return Ok(());
    }
    if wanted.is_empty() {
        *wanted = job
            .items()
            .map(|i| i.map(|i| i.record.id))
            .collect::<Result<_, _>>()?;
    }
    let asked = wanted.len();
    wanted.retain(|id| !dropped.contains(id));
    anyhow::ensure!(
        !wanted.is_empty(),
        "every item asked for is a near-duplicate --one-per-group leaves out (nothing written)"
    );
    eprintln!(
        "--one-per-group: {} near-duplicates left out",
        asked - wanted.len()
    );
    Ok(())
}

/// Runs `sparc3d export`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    // Messages name the job as given (a URL), not its local view.
    let named = args.job.clone();
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    for line in debris::clear(&args.out)? {
        eprintln!("{line}");
    }
    let job = Job::open(&args.job)?;
    let consumer = args.format;
    let frame = args.frame.unwrap_or(consumer.frames()[0]);
    match fit(&job, &named, consumer, frame) {
        Ok(warnings) => {
            for w in warnings {
                eprintln!("warning: --format {}: {w}", consumer.name());
            }
        }
        Err(refusal) => {
            eprintln!("error: {refusal}");
            return Ok(ExitCode::from(2));
        }
    }
    // Each `--ids` entry names an item as `--id` does elsewhere (whole id, unique prefix or
    // source file); a miss fails before anything is written, with the closest names.
    let mut wanted: BTreeSet<String> = BTreeSet::new();
    for query in &args.ids {
        wanted.insert(item_lookup::find(&job, query)?.record.id);
    }
    let filter = RowFilter::optional(&job, args.filter.as_deref())?;
    let dropped = args.dedup.dropped(&job, &named, filter.as_ref())?;
    leave_out_near_duplicates(&job, &mut wanted, &dropped)?;
    let staging = Staging::create(&args.out)?;
    let chosen = Chosen {
        ids: &wanted,
        filter: filter.as_ref(),
    };
    let written = items::write_items(&job, consumer, frame, &chosen, &staging);
    let root = std::path::absolute(&args.out)
        .with_context(|| format!("resolving {}", args.out.display()))?;
    let record = Record {
        job: &job.layout.root,
        fingerprint: job.fingerprint(),
        consumer,
        frame,
        filter: filter.as_ref().map(|f| f.text.as_str()),
    };
    let outcome = written.and_then(|w| {
        staging.finish(&record, &w, &root)?;
        Ok(w)
    });
    let outcome = match outcome {
        Ok(w) => w,
        Err(e) => {
            staging.discard();
            return Err(e);
        }
    };
    if let Some(left) = staging.move_to(&args.out)? {
        eprintln!("warning: {left}");
    }
    eprintln!(
        "{} items written to {} ({}, frame {}){}",
        outcome.listed.len(),
        args.out.display(),
        consumer.name(),
        frame.name(),
        outcome.counts()
    );
    // Items left out as the consumer's own pipeline leaves them do not fail the export.
    Ok(if outcome.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// Whether `consumer` takes the job (`named` as given) in `frame`: the warnings to show, or
/// why it refuses (a frame it has not, samples the job does not draw, settings its frame
/// needs), before anything is written.
fn fit(
    job: &Job,
    named: &std::path::Path,
    consumer: Consumer,
    frame: Frame,
) -> std::result::Result<Vec<String>, String> {
    let frames = consumer.frames();
    if !frames.contains(&frame) {
        return Err(format!(
            "--format {} is written in the frame{} {}, not {}",
            consumer.name(),
            if frames.len() > 1 { "s" } else { "" },
            frames
                .iter()
                .map(|f| f.name())
                .collect::<Vec<_>>()
                .join(", "),
            frame.name()
        ));
    }
    let samples = &job.file.config.samples;
    let missing = consumer.missing(samples.enabled.then_some(&samples.params));
    if !missing.is_empty() {
        return Err(format!(
            "{}: --format {} needs samples this job does not draw (nothing was written); make \
             a job with --for {} (samples on, whose defaults serve every consumer), or with \
             these [samples] keys:\n  {}",
            named.display(),
            consumer.name(),
            consumer.name(),
            missing.join("\n  ")
        ));
    }
    let check = consumer.check(&job.file.config.params, frame);
    if !check.required.is_empty() {
        return Err(format!(
            "{}: --format {} --frame {} needs a job converted with these settings; \
             initialise one with them (nothing was written):\n  {}",
            named.display(),
            consumer.name(),
            frame.name(),
            check.required.join("\n  ")
        ));
    }
    Ok(check.warnings)
}
