//! `sparc3d convert IN -o OUT`: one mesh through Sparcubes and back to a watertight mesh,
//! with a short summary (faces in/out, active vertices and cells, components, time per stage,
//! peak memory).

use anyhow::Context;
use serde_json::{json, Value};
use sparc3d_workers::item::convert::{convert_file, StageError, Steps};
use sparcubes::io::LoadStats;
use sparcubes::materials::TextureBudget;
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
    pub resolution: crate::flags::resolution::ResolutionArg,
    #[command(flatten)]
    pub conversion: crate::flags::conversion::ConversionArgs,
    #[command(flatten)]
    pub refine: crate::flags::refine::RefineArgs,
    /// Write the output in grid coordinates (voxels) instead of the source frame.
    #[arg(long)]
    pub grid_frame: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Also sample the source's appearance (base colour, metallic, roughness, alpha) at the
    /// active cells, as a job with `[attributes] enabled = true` does, summarise it, and write
    /// the output in colour (each vertex its cell's base colour and alpha; .ply, .obj, .glb).
    #[arg(long)]
    pub attributes: bool,
    /// Also compute the output's shape signature, as a job with `shape_signature = true`
    /// does (the stage `signature`; `--json` prints it as `shape_signature`).
    #[arg(long)]
    pub shape_signature: bool,
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
    let mut params = args.conversion.params(args.resolution.get());
    params.refine = args.refine.settings();
    super::check_params(&params)?;
    let steps = Steps {
        params: &params,
        input_components: true,
        extract: true,
        samples: None,
        keep_mesh: true,
        encode: None,
        attributes: args.attributes.then(TextureBudget::default),
        quality: true,
        signature: args.shape_signature,
        renders: None,
    };
    let done = convert_file(&args.input, steps).map_err(|failed| {
        let context = match failed.error {
            StageError::Load(_) => "loading",
            StageError::Attributes(_) => "reading the appearance of",
            _ => "converting",
        };
        anyhow::Error::new(failed.error).context(format!("{context} {}", args.input.display()))
    })?;
    let cubes = &done.conversion.cubes;
    let (Some(mut mesh), Some(input_components)) = (done.mesh, done.input_components) else {
        anyhow::bail!("the conversion path returned no mesh or component count");
    };
    let colours = done
        .attributes
        .as_ref()
        .map(|(cells, _)| crate::check::colours::of_vertices(cubes, cells, &mesh, &args.output));
    if !args.grid_frame {
        sparcubes::extract::to_source(&mut mesh, &cubes.normalization, cubes.resolution);
    }
    let (topo, check_seconds, save_seconds) =
        save_while_checking(&mesh, colours.as_deref(), &args.output)?;

    let s = &done.conversion.stats;
    let mut stages = done.seconds.in_order;
    stages.push(("check".into(), check_seconds));
    stages.push(("save".into(), save_seconds));
    let total = start.elapsed().as_secs_f64();
    let peak = crate::util::memory::peak_rss_bytes();
    let summary = json!({
        "input": args.input.display().to_string(),
        "output": args.output.display().to_string(),
        "resolution": args.resolution.get(),
        "deform": params.deform,
        "input_faces": s.input_faces,
        "input_vertices": s.input_vertices,
        "input_components": input_components,
        "degenerate_faces": s.degenerate_faces,
        "dropped_faces_bad_index": done.load_stats.faces_bad_index,
        "dropped_faces_non_finite": done.load_stats.faces_non_finite,
        "dropped_faces_duplicate": done.load_stats.faces_duplicate,
        "wall_cells": s.wall_cells,
        "active_vertices": s.active_vertices,
        "active_cells": s.active_cells,
        "shell_vertices": s.shell_vertices,
        "inside_test": params.inside_test,
        "seal_openings": params.seal_openings,
        "sealed_pockets": s.sealed_pockets,
        "enclosed_regions": s.enclosed_regions,
        "air_regions": s.air_regions,
        "ambiguous_regions": s.ambiguous_regions,
        "thin_parts": s.thin_parts,
        "shelled_thin_parts": s.shelled_thin_parts,
        "overlap_groups": s.overlap_groups,
        "refine": s.refine,
        "output_faces": mesh.triangles.len(),
        "output_vertices": mesh.positions.len(),
        "output_components": topo.components,
        "components_note": components_note(input_components, topo.components),
        "watertight": topo.is_watertight(),
        "manifold": topo.is_manifold(),
        "stage_seconds": stages.iter().map(|(k, v)| (k.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
        "total_seconds": total,
        "peak_rss_bytes": peak,
        "attributes": done.attributes.as_ref().map(|(cells, facts)| attributes_summary(cells, facts)),
        "quality": done.quality,
        "shape_signature": done.signature,
    });
    if args.json {
        println!("{summary}");
    } else {
        print_text(&summary, &done.load_stats, &stages);
    }
    Ok(ExitCode::SUCCESS)
}

/// Writes `mesh` to `output` and checks its topology while the file is synced to disk, and
/// returns the report, the check's seconds and the save's (writing, then waiting for the sync
/// and the rename once the check is done; so the stages still add up to the wall time).
///
/// The sync is most of a large output's save (docs/record/PERFORMANCE-history.md, "The
/// conversion stages (fifth part)"): it waits on the disk, not the CPU, so it runs on a thread
/// of its own while the check has the pool. The check reads only the triangles' vertex
/// indices for what the summary prints, so the frame the positions are in does not change its
/// answers.
fn save_while_checking(
    mesh: &sparcubes::TriMesh,
    colours: Option<&[[u8; 4]]>,
    output: &std::path::Path,
) -> anyhow::Result<(sparcubes::topology::TopologyReport, f64, f64)> {
    let writing = || format!("writing {}", output.display());
    let t = Instant::now();
    let pending = sparcubes::io::save_pending(mesh, colours, output).with_context(writing)?;
    let write_seconds = t.elapsed().as_secs_f64();
    std::thread::scope(|scope| {
        let sync = scope.spawn(|| pending.commit());
        let t = Instant::now();
        let topo = sparcubes::topology::check(mesh);
        let check_seconds = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let committed = sync
            .join()
            .map_err(|_| anyhow::anyhow!("{}: the thread syncing it panicked", writing()))?;
        committed.with_context(writing)?;
        Ok((
            topo,
            check_seconds,
            write_seconds + t.elapsed().as_secs_f64(),
        ))
    })
}

/// The summary of sampled attributes: what the appearance is made of and the cells' mean
/// values (base colour as the mean of the stored sRGB bytes).
fn attributes_summary(
    cells: &sparcubes::attributes::CellAttributes,
    facts: &sparc3d_schema::AppearanceFacts,
) -> Value {
    let n = cells.alpha.len().max(1) as f64;
    let mean = |v: &mut dyn Iterator<Item = u8>| v.map(f64::from).sum::<f64>() / n;
    let color = [0, 1, 2].map(|c| mean(&mut cells.base_color.iter().map(|p| p[c])));
    json!({
        "materials": facts.materials,
        "textures": facts.textures,
        "texture_max_size": facts.texture_max_size,
        "alpha_modes": facts.alpha_modes,
        "vertex_colors": facts.vertex_colors,
        "not_read": facts.not_read,
        "nearest_cells": facts.nearest_cells,
        "mean_base_color": color,
        "mean_metallic": mean(&mut cells.metallic.iter().copied()),
        "mean_roughness": mean(&mut cells.roughness.iter().copied()),
        "mean_alpha": mean(&mut cells.alpha.iter().copied()),
    })
}

/// Prints `convert`'s JSON summary for a reader, with the first dropped face from `load`.
fn print_text(v: &Value, load: &LoadStats, stages: &[(String, f64)]) {
    let text = |key: &str| v[key].as_str().unwrap_or_default().to_string();
    let deform = if v["deform"] == true {
        ""
    } else {
        " (no deformation)"
    };
    println!(
        "{} → {} at {}³{deform}",
        text("input"),
        text("output"),
        v["resolution"]
    );
    println!(
        "  faces        {} in ({} components) → {} out ({} components)",
        v["input_faces"], v["input_components"], v["output_faces"], v["output_components"]
    );
    if let Some(note) = v["components_note"].as_str() {
        println!("  note         {note}");
    }
    if load.faces_bad_index + load.faces_non_finite > 0 {
        println!(
            "  dropped      {} faces with a bad vertex index{}, {} with a non-finite coordinate",
            load.faces_bad_index,
            load.first_bad_face
                .as_deref()
                .map(|p| format!(" (first: {p})"))
                .unwrap_or_default(),
            load.faces_non_finite
        );
    }
    if load.faces_duplicate > 0 {
        println!(
            "  duplicates   {} faces dropped: each repeats an earlier face's vertices",
            load.faces_duplicate
        );
    }
    println!(
        "  active       {} vertices, {} cells ({} in thin shells)",
        v["active_vertices"], v["active_cells"], v["shell_vertices"]
    );
    if v["inside_test"] == true {
        println!(
            "  inside test  {} enclosed regions ({} air, {} ambiguous kept solid); thin closed parts: {} kept, {} as shells; {} sealed overlaps of parts",
            v["enclosed_regions"], v["air_regions"], v["ambiguous_regions"], v["thin_parts"], v["shelled_thin_parts"], v["overlap_groups"]
        );
    }
    if v["seal_openings"] == true {
        println!(
            "  openings     {} nearly closed parts kept solid (small openings sealed)",
            v["sealed_pockets"]
        );
    }
    let r = &v["refine"];
    if !r.is_null() {
        println!(
            "  refine       {}: loss {:.4} → {:.4} (step {} of {}), {} vertices moved, {} pixels compared",
            r["outcome"].as_str().unwrap_or_default(),
            r["loss_first"].as_f64().unwrap_or_default(),
            r["loss_best"].as_f64().unwrap_or_default(),
            r["best_step"], r["steps"], r["moved_vertices"], r["compared_pixels"]
        );
    }
    println!(
        "  watertight   {}, manifold {}",
        v["watertight"], v["manifold"]
    );
    print_attributes(&v["attributes"]);
    let parts: Vec<String> = stages
        .iter()
        .map(|(k, v)| format!("{k} {:.3}s", v))
        .collect();
    let total = v["total_seconds"].as_f64().unwrap_or_default();
    println!("  time         {:.3}s: {}", total, parts.join(", "));
    if let Some(p) = v["peak_rss_bytes"].as_u64() {
        println!("  peak memory  {:.1} MB", p as f64 / 1e6);
    }
}

/// Prints the attributes part of the summary, when there is one.
fn print_attributes(a: &Value) {
    if a.is_null() {
        return;
    }
    let c = &a["mean_base_color"];
    println!(
        "  attributes   {} materials, {} textures (largest {} px), alpha modes {}, vertex colours {}; \
         mean base colour ({:.0}, {:.0}, {:.0}), metallic {:.0}, roughness {:.0}, alpha {:.0}; \
         {} cells from the nearest surface",
        a["materials"], a["textures"], a["texture_max_size"], a["alpha_modes"], a["vertex_colors"],
        c[0].as_f64().unwrap_or_default(), c[1].as_f64().unwrap_or_default(),
        c[2].as_f64().unwrap_or_default(), a["mean_metallic"].as_f64().unwrap_or_default(),
        a["mean_roughness"].as_f64().unwrap_or_default(), a["mean_alpha"].as_f64().unwrap_or_default(),
        a["nearest_cells"]
    );
    for item in a["not_read"].as_array().into_iter().flatten() {
        println!("  not read     {}", item.as_str().unwrap_or_default());
    }
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
