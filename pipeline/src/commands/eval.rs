//! `sparc3d eval SOURCE OUTPUT`: quality of an extracted mesh against its source
//! (Chamfer distance, normal consistency, F1, components kept, offset; docs/QUALITY.md,
//! "How we measure").
//!
//! `sparc3d eval JOB --sample N`: the same for a reproducible sample of a job's `ok` items
//! (the sampler of `sparc3d validate`): each row is decoded, its mesh extracted in the source
//! frame and measured against the source file of its `uri`; per-item rows, then medians.

use crate::rows::sample::{self, SampleSize};
use crate::util::stats::median;
use anyhow::{bail, Context};
use serde_json::{json, Value};
use sparc3d_metrics::{evaluate, EvalOptions, QualityReport};
use sparc3d_schema::ShardRow;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Items evaluated from a job when `--sample` is not given.
const DEFAULT_JOB_SAMPLE: SampleSize = SampleSize::Count(10);

/// Arguments of `sparc3d eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The source mesh (OBJ, PLY, STL, OFF, glTF, GLB), or a job folder (then OUTPUT is left
    /// out and a sample of the job's items is measured against their sources).
    pub source: PathBuf,
    /// The mesh to measure against it, in the same frame (e.g. the output of `convert`).
    pub output: Option<PathBuf>,
    /// Grid resolution N that voxel units refer to (a voxel is 1/N of the source's longest
    /// side); for a job, each item's unless given.
    #[command(flatten)]
    pub resolution: crate::flags::resolution::ResolutionArg,
    /// For a job: how many `ok` items to measure, a count (`20`) or a percentage (`2%`);
    /// default 10.
    #[arg(long)]
    pub sample: Option<SampleSize>,
    /// For a job: seed of the item sample (the same items as `sparc3d validate --seed`).
    #[arg(long, default_value_t = 0)]
    pub sample_seed: u64,
    /// Points sampled on each mesh.
    #[arg(long, default_value_t = EvalOptions::default().samples)]
    pub samples: usize,
    /// Seed of the sampling.
    #[arg(long, default_value_t = EvalOptions::default().seed)]
    pub seed: u64,
    /// Print the report as one line of JSON.
    #[arg(long)]
    pub json: bool,
}

/// Runs `sparc3d eval`.
pub fn run(mut args: Args) -> anyhow::Result<ExitCode> {
    args.source = crate::job::bucket_home::local_view(&args.source)?;
    if args.source.join("job.json").is_file() {
        if let Some(out) = &args.output {
            bail!(
                "{} is a job folder: leave out OUTPUT ({}) and use --sample",
                args.source.display(),
                out.display()
            );
        }
        return run_job(&args);
    }
    let Some(output_path) = &args.output else {
        bail!(
            "missing OUTPUT: `sparc3d eval SOURCE OUTPUT`, or `sparc3d eval JOB --sample N` \
             for a job folder"
        );
    };
    if args.sample.is_some() {
        bail!(
            "--sample is for a job folder, and {} is not one",
            args.source.display()
        );
    }
    let source = load(&args.source)?;
    let output = load(output_path)?;
    let options = EvalOptions {
        samples: args.samples,
        seed: args.seed,
        resolution: args.resolution.get(),
    };
    let report = evaluate(&source, &output, &options).with_context(|| {
        format!(
            "evaluating {} against {}",
            output_path.display(),
            args.source.display()
        )
    })?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", table(&report));
    }
    Ok(ExitCode::SUCCESS)
}

/// Decodes a row, extracts its mesh in the source frame and measures it against the source.
fn eval_row(row: &ShardRow, args: &Args) -> anyhow::Result<QualityReport> {
    let cubes = row
        .cubes()
        .with_context(|| format!("item {:?}: decoding its row", row.id))?;
    let output = sparcubes::extract::extract_to_source(&cubes);
    let source = sparc3d_workers::item::source::load_mesh(&row.uri)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("item {:?}", row.id))?
        .mesh;
    let options = EvalOptions {
        samples: args.samples,
        seed: args.seed,
        resolution: args.resolution.or(row.resolution),
    };
    evaluate(&source, &output, &options)
        .with_context(|| format!("item {:?}: evaluating against {}", row.id, row.uri))
}

/// `sparc3d eval JOB --sample N`.
fn run_job(args: &Args) -> anyhow::Result<ExitCode> {
    let job = crate::job::setup::open_read_only(&args.source)?;
    let size = args.sample.unwrap_or(DEFAULT_JOB_SAMPLE);
    let drawn = sample::draw(&job, size, args.sample_seed)?;
    eprintln!(
        "evaluating {} of {} ok items of {} (sample {size}, seed {})",
        drawn.items.len(),
        drawn.population,
        args.source.display(),
        args.sample_seed
    );
    let mut items: Vec<Value> = Vec::new();
    let mut reports: Vec<QualityReport> = Vec::new();
    let mut errors = 0usize;
    if !args.json {
        println!(
            "{:>6}  {:<16}  {:>8}  {:>9}  {:>6}  {:>7}  {:>7}  {:>7}  {:>9}  {:>8}",
            "item",
            "id",
            "faces",
            "cd (vox)",
            "anc",
            "F1@.002",
            "F1@.005",
            "F1@.01",
            "kept",
            "offset"
        );
    }
    sample::for_each_sampled_row(&job, &drawn, |row| {
        let base = json!({"item_index": row.item_index, "id": row.id, "uri": row.uri});
        match eval_row(&row, args) {
            Ok(r) => {
                if !args.json {
                    println!("{}", item_line(row.item_index, &row.id, &r));
                }
                let mut v = base;
                v["report"] = serde_json::to_value(&r)?;
                items.push(v);
                reports.push(r);
            }
            Err(e) => {
                errors += 1;
                eprintln!("error: {e:#}");
                let mut v = base;
                v["error"] = json!(format!("{e:#}"));
                items.push(v);
            }
        }
        Ok(())
    })?;
    let medians = medians(&reports);
    if args.json {
        let v = json!({
            "job": args.source,
            "population": drawn.population,
            "sample": size.to_string(),
            "sample_seed": args.sample_seed,
            "evaluated": reports.len(),
            "errors": errors,
            "items": items,
            "median": medians,
        });
        println!("{}", serde_json::to_string(&v)?);
    } else {
        let f = |k: &str, d: usize| {
            medians[k]
                .as_f64()
                .map_or("n/a".to_string(), |x| format!("{x:.d$}"))
        };
        println!(
            "{:>6}  {:<16}  {:>8}  {:>9}  {:>6}  {:>7}  {:>7}  {:>7}  {:>9}  {:>8}",
            "median",
            format!("({} items)", reports.len()),
            f("output_faces", 0),
            f("cd_voxels", 3),
            f("anc", 2),
            f("f1_0.002", 2),
            f("f1_0.005", 2),
            f("f1_0.01", 2),
            f("components_kept_fraction", 3),
            f("offset_voxels", 3),
        );
    }
    Ok(if errors > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// One table line of a job item's report.
fn item_line(item_index: u64, id: &str, r: &QualityReport) -> String {
    let short: String = id.chars().take(16).collect();
    let f1 = |i: usize| r.f1.get(i).map_or("n/a".into(), |f| format!("{:.2}", f.f1));
    format!(
        "{item_index:>6}  {short:<16}  {:>8}  {:>9.3}  {:>6.2}  {:>7}  {:>7}  {:>7}  {:>9}  {:>8}",
        r.output_faces,
        r.cd_voxels,
        r.anc,
        f1(0),
        f1(1),
        f1(2),
        format!("{}/{}", r.components_kept, r.components_total),
        r.offset_voxels.map_or("n/a".into(), |o| format!("{o:+.3}")),
    )
}

/// Medians over the evaluated items of the main numbers.
fn medians(reports: &[QualityReport]) -> Value {
    let m = |f: &dyn Fn(&QualityReport) -> Option<f64>| {
        median(&reports.iter().filter_map(f).collect::<Vec<_>>())
    };
    let mut v = json!({
        "output_faces": m(&|r| Some(r.output_faces as f64)),
        "cd": m(&|r| Some(r.cd)),
        "cd_voxels": m(&|r| Some(r.cd_voxels)),
        "cd_surface": m(&|r| Some(r.cd_surface)),
        "anc": m(&|r| Some(r.anc)),
        "components_kept_fraction": m(&|r| {
            (r.components_total > 0)
                .then(|| r.components_kept as f64 / r.components_total as f64)
        }),
        "offset_voxels": m(&|r| r.offset_voxels),
        "output_to_source_voxels": m(&|r| Some(r.output_to_source_voxels)),
    });
    for (i, t) in sparc3d_metrics::F1_THRESHOLDS.iter().enumerate() {
        v[format!("f1_{t}")] = json!(m(&|r| r.f1.get(i).map(|f| f.f1)));
    }
    v
}

/// Loads a mesh, naming the file in the error.
fn load(path: &Path) -> anyhow::Result<sparcubes::TriMesh> {
    let loaded =
        sparcubes::io::load(path).with_context(|| format!("loading {}", path.display()))?;
    Ok(loaded.mesh)
}

/// The report as a readable two-column table.
fn table(r: &QualityReport) -> String {
    let n = r.options.resolution;
    let mut rows: Vec<(String, String)> = vec![
        (
            "faces (source / output)".into(),
            format!("{} / {}", r.source_faces, r.output_faces),
        ),
        ("samples per mesh".into(), r.options.samples.to_string()),
        (
            "chamfer cd".into(),
            format!("{:.6}  ({:.3} voxels at N={n})", r.cd, r.cd_voxels),
        ),
        (
            "  sampling floor".into(),
            format!("{:.6}  ({:.3} voxels)", r.cd_floor, r.cd_floor * n as f64),
        ),
        (
            "  point-to-surface".into(),
            format!(
                "{:.6}  ({:.3} voxels)",
                r.cd_surface,
                r.cd_surface * n as f64
            ),
        ),
        ("normal consistency".into(), format!("{:.2}", r.anc)),
    ];
    for f in &r.f1 {
        rows.push((
            format!("F1 @ {}", f.threshold),
            format!(
                "{:.2}  (precision {:.2}, recall {:.2})",
                f.f1, f.precision, f.recall
            ),
        ));
    }
    rows.push((
        "components kept".into(),
        format!(
            "{} / {}  ({} in all, {} under 2 voxels)",
            r.components_kept,
            r.components_total,
            r.source_components,
            r.source_components - r.components_total
        ),
    ));
    rows.push((
        "source closed".into(),
        if r.source_closed { "yes" } else { "no" }.into(),
    ));
    rows.push((
        "output closed".into(),
        if r.output_closed { "yes" } else { "no" }.into(),
    ));
    rows.push((
        "offset (voxels)".into(),
        match r.offset_voxels {
            Some(o) => format!("{o:+.3}  (positive: output outside the source)"),
            None => "n/a (source not closed)".into(),
        },
    ));
    rows.push((
        "output→source (voxels)".into(),
        format!("{:.3}", r.output_to_source_voxels),
    ));
    let width = rows
        .iter()
        .map(|(k, _)| k.chars().count())
        .max()
        .unwrap_or(0);
    rows.iter()
        .map(|(k, v)| format!("{k:<width$}  {v}\n"))
        .collect()
}
