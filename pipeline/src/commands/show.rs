//! `sparc3d show JOB --id X -o mesh.ply`: decodes one item's row and writes its extracted
//! mesh, exactly as `sparc3d convert` would with the job's parameters (in colour when the job
//! stores attributes, as `convert --attributes` writes it).

use crate::rows::item_lookup;
use anyhow::{Context, Result};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d show`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder, or the bucket prefix that is the job's home (read through a local copy).
    pub job: PathBuf,
    /// Item: its id, a unique prefix of it, or its source file's path or name (`sparc3d ls
    /// JOB` lists the items with their ids).
    #[arg(long)]
    pub id: String,
    /// Output mesh (.ply, .obj, .stl, .glb).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write the mesh in grid coordinates (voxels) instead of the source frame.
    #[arg(long)]
    pub grid_frame: bool,
    /// Also write the decoded tensors (coords, sdf, deformation, cells) as JSON to this file.
    #[arg(long)]
    pub tensors_json: Option<PathBuf>,
}

/// Runs `sparc3d show`.
pub fn run(mut args: Args) -> Result<ExitCode> {
    args.job = crate::job::bucket_home::local_view(&args.job)?;
    let job = crate::job::setup::open_read_only(&args.job)?;
    let item = item_lookup::find(&job, &args.id)?;
    // The shard is hashed against its completion record before its row is trusted.
    let row = item_lookup::row(&job, &item)?;
    let cubes = item_lookup::cubes(&row)?;
    if let Some(path) = &args.tensors_json {
        let v = serde_json::json!({
            "id": row.id,
            "resolution": cubes.resolution,
            "center": cubes.normalization.center,
            "scale": cubes.normalization.scale,
            "coords": cubes.coords,
            "sdf": cubes.sdf,
            "deformation": cubes.deformation,
            "cells": cubes.cells,
        });
        std::fs::write(path, serde_json::to_vec(&v)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let mut mesh = sparcubes::extract(&cubes);
    let attributes = match row.tensors.as_ref().and_then(|t| t.attributes.as_ref()) {
        Some(a) => Some(
            a.to_attributes()
                .with_context(|| format!("decoding the attributes of {}", row.id))?,
        ),
        None => None,
    };
    let colours = attributes
        .as_ref()
        .map(|cells| crate::check::colours::of_vertices(&cubes, cells, &mesh, &args.output));
    if !args.grid_frame {
        sparcubes::extract::to_source(&mut mesh, &cubes.normalization, cubes.resolution);
    }
    let saved = match &colours {
        Some(colours) => sparcubes::io::save_coloured(&mesh, colours, &args.output),
        None => sparcubes::io::save(&mesh, &args.output),
    };
    saved.with_context(|| format!("writing {}", args.output.display()))?;
    eprintln!(
        "{} ({}): {} faces written to {}",
        row.id,
        row.uri,
        mesh.triangles.len(),
        args.output.display()
    );
    Ok(ExitCode::SUCCESS)
}
