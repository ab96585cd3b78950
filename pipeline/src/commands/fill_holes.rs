//! `sparc3d fill-holes IN -o OUT`: close the holes of a mesh (e.g. one decoded from a VAE) by
//! smallest-angle ear filling, and report what was filled and whether the result is closed.
//! [`fill_and_check`] and [`summary_fields`] are the step `sparc3d extract --fill-holes` shares.

use anyhow::Context;
use serde_json::{json, Map, Value};
use sparcubes::holes::HoleStats;
use sparcubes::mesh::TriMesh;
use sparcubes::topology::{self, TopologyReport};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d fill-holes`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input mesh (OBJ, PLY, STL, OFF, glTF, GLB).
    pub input: PathBuf,
    /// Output mesh (.ply, .obj, .stl, .glb).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Fills every hole of an indexed mesh (paper §3.4) and checks the result's topology.
pub fn fill_and_check(mesh: &TriMesh) -> (TriMesh, HoleStats, TopologyReport) {
    let (filled, stats) = sparcubes::holes::fill_holes(mesh);
    let report = topology::check(&filled);
    (filled, stats, report)
}

/// The JSON fields that describe a filling: holes found and filled, triangles added, what is
/// left open.
pub fn summary_fields(stats: &HoleStats, after: &TopologyReport) -> Map<String, Value> {
    let v = json!({
        "holes": stats.holes,
        "filled": stats.filled,
        "unfilled": stats.unfilled,
        "triangles_added": stats.triangles_added,
        "largest_hole": stats.largest_hole,
        "open_boundary_edges": stats.open_boundary_edges,
        "boundary_edges_after": after.boundary_edges,
        "non_manifold_edges_after": after.non_manifold_edges,
        "watertight": after.is_watertight(),
    });
    match v {
        Value::Object(m) => m,
        _ => Map::new(),
    }
}

/// One line saying what a filling did.
pub fn summary_line(stats: &HoleStats, after: &TopologyReport) -> String {
    format!(
        "{} holes, {} filled ({} triangles added, largest {} edges); \
         {} boundary edges left, watertight: {}",
        stats.holes,
        stats.filled,
        stats.triangles_added,
        stats.largest_hole,
        after.boundary_edges,
        after.is_watertight(),
    )
}

/// Runs `sparc3d fill-holes`. Vertices at identical positions are merged first, so
/// unindexed formats (STL) have their holes found too.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let loaded = sparcubes::io::load(&args.input)
        .with_context(|| format!("loading {}", args.input.display()))?;
    let welded = topology::weld(&loaded.mesh);
    let (mesh, stats, report) = fill_and_check(&welded);
    sparcubes::io::save(&mesh, &args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if args.json {
        let mut summary = Map::new();
        summary.insert("input".into(), json!(args.input.display().to_string()));
        summary.insert("output".into(), json!(args.output.display().to_string()));
        summary.extend(summary_fields(&stats, &report));
        println!("{}", Value::Object(summary));
    } else {
        println!(
            "{}: {}",
            args.input.display(),
            summary_line(&stats, &report)
        );
    }
    Ok(ExitCode::SUCCESS)
}
