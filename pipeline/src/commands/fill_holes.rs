//! `sparc3d fill-holes IN -o OUT`: close the holes of a mesh (e.g. one decoded from a VAE) by
//! smallest-angle ear filling, and report what was filled and whether the result is closed.

use anyhow::Context;
use sparcubes::topology;
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

/// Runs `sparc3d fill-holes`. Vertices at identical positions are merged first, so
/// unindexed formats (STL) have their holes found too.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let loaded = sparcubes::io::load(&args.input)
        .with_context(|| format!("loading {}", args.input.display()))?;
    let welded = topology::weld(&loaded.mesh);
    let (mesh, stats) = sparcubes::holes::fill_holes(&welded);
    let report = topology::check(&mesh);
    sparcubes::io::save(&mesh, &args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if args.json {
        let summary = serde_json::json!({
            "input": args.input.display().to_string(),
            "output": args.output.display().to_string(),
            "holes": stats.holes,
            "filled": stats.filled,
            "unfilled": stats.unfilled,
            "triangles_added": stats.triangles_added,
            "largest_hole": stats.largest_hole,
            "open_boundary_edges": stats.open_boundary_edges,
            "boundary_edges_after": report.boundary_edges,
            "non_manifold_edges_after": report.non_manifold_edges,
            "watertight": report.is_watertight(),
        });
        println!("{summary}");
    } else {
        println!(
            "{}: {} holes, {} filled ({} triangles added, largest {} edges); \
             {} boundary edges left, watertight: {}",
            args.input.display(),
            stats.holes,
            stats.filled,
            stats.triangles_added,
            stats.largest_hole,
            report.boundary_edges,
            report.is_watertight(),
        );
    }
    Ok(ExitCode::SUCCESS)
}
