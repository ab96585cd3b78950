//! `sparc3d extract TENSORS -o mesh.ply [--id X] [--fill-holes]`: the mesh of sparse cubes
//! stored in a tensor file (or a shard), with the extraction `show` and `convert` use; e.g. for
//! the cubes a VAE decoded (`sparc3d-vae decode`), so that no other program re-implements
//! marching cubes. A tensor file is a Parquet file with the shard's `id`, `resolution`,
//! normalization and cube tensor columns in the shard encoding (docs/FORMAT.md, "Tensor files").

use crate::commands::fill_holes;
use anyhow::{bail, Context, Result};
use serde_json::{json, Map, Value};
use sparc3d_workers::store::read::for_each_batch;
use sparcubes::SparseCubes;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d extract`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Tensor file or shard (Parquet) holding the sparse cubes.
    pub tensors: PathBuf,
    /// Item id; may be left out when the file holds one row.
    #[arg(long)]
    pub id: Option<String>,
    /// Output mesh (.ply, .obj, .stl, .glb).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Complete the grid first, so that the mesh is closed by construction: missing vertices
    /// next to active ones get the sign of their region (outside when it reaches the grid's
    /// border, else that of most of its active neighbours) and φ = ±0.5 voxel. For grids whose
    /// active set may end where the surface does not, e.g. a VAE's decoded grid.
    #[arg(long)]
    pub close: bool,
    /// Close the mesh's holes by smallest-angle ear filling (paper §3.4, as `fill-holes`).
    #[arg(long)]
    pub fill_holes: bool,
    /// Write the mesh in grid coordinates (voxels) instead of the source frame.
    #[arg(long)]
    pub grid_frame: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The cubes of the requested row: the one with `id`, or the only row.
fn find_cubes(args: &Args) -> Result<(String, SparseCubes)> {
    let path = &args.tensors;
    let mut found: Option<(String, Result<SparseCubes, sparc3d_schema::SchemaError>)> = None;
    let mut rows = 0usize;
    for_each_batch(path, |batch| {
        let decoded = sparc3d_schema::columns::arrow::batch_to_cubes(&batch)
            .with_context(|| format!("decoding {}", path.display()))?;
        for (id, cubes) in decoded {
            rows += 1;
            let wanted = args.id.as_deref().is_none_or(|w| w == id);
            if wanted && found.is_none() {
                found = Some((id, cubes));
            }
        }
        anyhow::Ok(())
    })?;
    if args.id.is_none() && rows > 1 {
        bail!("{} holds {rows} rows: choose one with --id", path.display());
    }
    let Some((id, cubes)) = found else {
        match &args.id {
            Some(id) => bail!("no row with id {id:?} in {}", path.display()),
            None => bail!("{} holds no rows", path.display()),
        }
    };
    let cubes = cubes.with_context(|| format!("item {id:?} in {}", path.display()))?;
    if cubes.cells.is_empty() {
        bail!(
            "item {id:?} in {}: no active cells, so no surface to extract",
            path.display()
        );
    }
    Ok((id, cubes))
}

/// |φ| of the vertices `--close` adds, in voxels: the surface between an active vertex and an
/// added one then lies within their edge, nearer the active one when its |φ| is small.
const CLOSE_FILL: f32 = 0.5;

/// Runs `sparc3d extract`.
pub fn run(args: Args) -> Result<ExitCode> {
    let (id, mut cubes) = find_cubes(&args)?;
    let mut summary = Map::new();
    if args.close {
        let (closed, stats) = sparcubes::close_grid::close_grid(&cubes, CLOSE_FILL);
        summary.insert("close_added_vertices".into(), json!(stats.added_vertices));
        summary.insert("close_added_inside".into(), json!(stats.added_inside));
        summary.insert("close_border_clamped".into(), json!(stats.border_clamped));
        summary.insert("cells_before_close".into(), json!(cubes.cells.len()));
        cubes = closed;
    }
    let mut mesh = sparcubes::extract(&cubes);
    let before = sparcubes::topology::check(&mesh);
    summary.insert("id".into(), json!(id));
    summary.insert("output".into(), json!(args.output.display().to_string()));
    summary.insert("active_cells".into(), json!(cubes.cells.len()));
    summary.insert("boundary_edges_before".into(), json!(before.boundary_edges));
    summary.insert(
        "non_manifold_edges_before".into(),
        json!(before.non_manifold_edges),
    );
    summary.insert("watertight_before".into(), json!(before.is_watertight()));
    let mut line = format!(
        "{id}: {} faces, {} boundary edges",
        mesh.triangles.len(),
        before.boundary_edges
    );
    let written = if args.fill_holes {
        let (filled, stats, after) = fill_holes::fill_and_check(&mesh);
        mesh = filled;
        summary.extend(fill_holes::summary_fields(&stats, &after));
        line = format!("{line}; {}", fill_holes::summary_line(&stats, &after));
        after
    } else {
        summary.insert("watertight".into(), json!(before.is_watertight()));
        before
    };
    // The pieces of the mesh written (triangles connected through shared vertices), so that a
    // caller (the VAE's evaluation) counts them without reading the file back.
    summary.insert("components".into(), json!(written.components));
    summary.insert("faces".into(), json!(mesh.triangles.len()));
    summary.insert("vertices".into(), json!(mesh.positions.len()));
    if !args.grid_frame {
        sparcubes::extract::to_source(&mut mesh, &cubes.normalization, cubes.resolution);
    }
    sparcubes::io::save(&mesh, &args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    if args.json {
        println!("{}", Value::Object(summary));
    } else {
        println!("{line} → {}", args.output.display());
    }
    Ok(ExitCode::SUCCESS)
}
