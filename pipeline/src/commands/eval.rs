//! `sparc3d eval SOURCE OUTPUT`: quality of an extracted mesh against its source
//! (Chamfer distance, normal consistency, F1, components kept, offset; DESIGN.md §6).

use anyhow::Context;
use sparcubes::metrics::{evaluate, EvalOptions, QualityReport};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The source mesh (OBJ, PLY, STL, OFF, glTF, GLB).
    pub source: PathBuf,
    /// The mesh to measure against it, in the same frame (e.g. the output of `convert`).
    pub output: PathBuf,
    /// Grid resolution N that voxel units refer to (a voxel is 1/N of the source's longest
    /// side).
    #[arg(long, default_value_t = 512)]
    pub resolution: u32,
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
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let source = load(&args.source)?;
    let output = load(&args.output)?;
    let options = EvalOptions {
        samples: args.samples,
        seed: args.seed,
        resolution: args.resolution,
    };
    let report = evaluate(&source, &output, &options).with_context(|| {
        format!(
            "evaluating {} against {}",
            args.output.display(),
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
