//! `sparc3d convert IN -o OUT`: one mesh through Sparcubes and back to a watertight mesh,
//! with a short summary (faces in/out, active vertices and cells, components, time per stage,
//! peak memory).

use anyhow::Context;
use serde_json::json;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `sparc3d convert`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input mesh (OBJ, PLY, STL, OFF, glTF, GLB).
    pub input: PathBuf,
    /// Output mesh (.ply, .obj, .stl, .glb), in the source's coordinate frame.
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub resolution: crate::resolution_arg::ResolutionArg,
    #[command(flatten)]
    pub deform: super::deform_args::DeformArgs,
    /// Write the output in grid coordinates (voxels) instead of the source frame.
    #[arg(long)]
    pub grid_frame: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Peak resident set size of this process in bytes (Linux `VmHWM`), if known.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Why an output can have more components than its input, when it has: read without it, the
/// summary looks like a part broke apart (docs/VALIDATION.md, the `components` check).
pub fn components_note(input: u64, output: u64) -> Option<&'static str> {
    (output > input).then_some(
        "more components out than in is expected: open parts become thin closed shells, and a \
         sheet or open part inside a closed one becomes a cavity, a closed surface of its own \
         (nothing is split off or lost; docs/VALIDATION.md)",
    )
}

/// Runs `sparc3d convert`.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let start = Instant::now();
    let loaded = sparcubes::io::load(&args.input)
        .with_context(|| format!("loading {}", args.input.display()))?;
    let load_seconds = start.elapsed().as_secs_f64();
    let mut params = sparcubes::Params::with_resolution(args.resolution.get());
    params.deform = args.deform.enabled();
    let conversion = sparcubes::convert(&loaded.mesh, &params)
        .with_context(|| format!("converting {}", args.input.display()))?;
    let t = Instant::now();
    let cubes = &conversion.cubes;
    let mut mesh = sparcubes::extract(cubes);
    let extract_seconds = t.elapsed().as_secs_f64();
    let topo = sparcubes::topology::check(&mesh);
    if !args.grid_frame {
        sparcubes::extract::to_source(&mut mesh, &cubes.normalization, cubes.resolution);
    }
    let t = Instant::now();
    sparcubes::io::save(&mesh, &args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let save_seconds = t.elapsed().as_secs_f64();
    let input_components =
        sparcubes::topology::check(&sparcubes::topology::weld(&loaded.mesh)).components;

    let s = &conversion.stats;
    let mut stages: Vec<(&str, f64)> = vec![("load", load_seconds)];
    stages.extend(s.stage_seconds.iter().cloned());
    stages.push(("extract", extract_seconds));
    stages.push(("save", save_seconds));
    let total = start.elapsed().as_secs_f64();
    let peak = peak_rss_bytes();
    let summary = json!({
        "input": args.input.display().to_string(),
        "output": args.output.display().to_string(),
        "resolution": args.resolution.get(),
        "deform": params.deform,
        "input_faces": s.input_faces,
        "input_vertices": s.input_vertices,
        "input_components": input_components,
        "degenerate_faces": s.degenerate_faces,
        "dropped_faces_bad_index": loaded.stats.faces_bad_index,
        "dropped_faces_non_finite": loaded.stats.faces_non_finite,
        "wall_cells": s.wall_cells,
        "active_vertices": s.active_vertices,
        "active_cells": s.active_cells,
        "shell_vertices": s.shell_vertices,
        "output_faces": mesh.triangles.len(),
        "output_vertices": mesh.positions.len(),
        "output_components": topo.components,
        "components_note": components_note(input_components, topo.components),
        "watertight": topo.is_watertight(),
        "manifold": topo.is_manifold(),
        "stage_seconds": stages.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "total_seconds": total,
        "peak_rss_bytes": peak,
    });
    if args.json {
        println!("{summary}");
    } else {
        println!(
            "{} → {} at {}³{}",
            args.input.display(),
            args.output.display(),
            args.resolution.get(),
            if params.deform {
                ""
            } else {
                " (no deformation)"
            }
        );
        println!(
            "  faces        {} in ({} components) → {} out ({} components)",
            s.input_faces,
            input_components,
            mesh.triangles.len(),
            topo.components
        );
        if let Some(note) = components_note(input_components, topo.components) {
            println!("  note         {note}");
        }
        let st = &loaded.stats;
        if st.faces_bad_index + st.faces_non_finite > 0 {
            println!(
                "  dropped      {} faces with a bad vertex index{}, {} with a non-finite coordinate",
                st.faces_bad_index,
                st.first_bad_face
                    .as_deref()
                    .map(|p| format!(" (first: {p})"))
                    .unwrap_or_default(),
                st.faces_non_finite
            );
        }
        println!(
            "  active       {} vertices, {} cells ({} in thin shells)",
            s.active_vertices, s.active_cells, s.shell_vertices
        );
        println!(
            "  watertight   {}, manifold {}",
            topo.is_watertight(),
            topo.is_manifold()
        );
        let parts: Vec<String> = stages
            .iter()
            .map(|(k, v)| format!("{k} {:.3}s", v))
            .collect();
        println!("  time         {:.3}s: {}", total, parts.join(", "));
        if let Some(p) = peak {
            println!("  peak memory  {:.1} MB", p as f64 / 1e6);
        }
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::components_note;

    #[test]
    fn more_components_out_than_in_are_explained() {
        assert!(components_note(2, 3).is_some_and(|n| n.contains("shells")));
        assert_eq!(components_note(3, 3), None);
        assert_eq!(
            components_note(51, 4),
            None,
            "parts closer than a voxel merge"
        );
    }
}
