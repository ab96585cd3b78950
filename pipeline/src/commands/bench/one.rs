//! `sparc3d bench-one MESH --resolution N` (hidden): converts one mesh at one resolution and
//! prints one JSON line ([`BenchRow`]) with the seconds of every stage (load, the conversion
//! stages, extraction, encoding), the counts, the compressed size of the tensors and the peak
//! RSS of this process. `sparc3d bench` runs it once per mesh in a subprocess, so that the
//! peak RSS is per mesh and a crash of one mesh is one failed row.

use crate::util::memory::peak_rss_bytes;
use anyhow::Context;
use serde::{Deserialize, Serialize};
use sparc3d_workers::item::convert::{convert_file, Encoding, Failed, StageError, Steps};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d bench-one`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input mesh (OBJ, PLY, STL, OFF, glTF, GLB).
    pub input: PathBuf,
    #[command(flatten)]
    pub resolution: crate::flags::resolution::ResolutionArg,
    #[command(flatten)]
    pub measured: super::measured::MeasuredConversion,
}

/// Compressed bytes of each stored tensor (zstd frames as `sparc3d-schema` encodes them).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TensorBytes {
    /// Active vertex coordinates, `n × 3` `<u2`.
    pub coords: u64,
    /// Signed distance per vertex, `n` `<f4`.
    pub sdf: u64,
    /// Displacement per vertex, `n × 3` `<f4`.
    pub deformation: u64,
    /// Active cells, `m × 3` `<u2`.
    pub cells: u64,
}

impl TensorBytes {
    /// Sum over the four tensors.
    pub fn total(&self) -> u64 {
        self.coords + self.sdf + self.deformation + self.cells
    }
}

/// One benchmark measurement: one mesh at one resolution. The converting process fills the
/// timings and counts; the benchmark driver adds what it sees from outside (wall time of the
/// process, CPU seconds, peak RSS from the kernel, exit status, failure).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct BenchRow {
    /// The mesh file.
    pub path: String,
    /// Grid resolution N.
    pub resolution: u32,
    /// Whether the mesh was converted, extracted and encoded.
    pub ok: bool,
    /// Why not, when `ok` is false (which stage, or how the process ended).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Seconds per stage in order: `load`, the conversion stages, `extract`, `encode`.
    #[serde(default)]
    pub stages: Vec<(String, f64)>,
    /// Sum of `stages` (seconds inside the process, without its start-up).
    #[serde(default)]
    pub total_seconds: f64,
    /// Input triangles.
    #[serde(default)]
    pub input_faces: u64,
    /// Input vertices.
    #[serde(default)]
    pub input_vertices: u64,
    /// Active grid vertices stored.
    #[serde(default)]
    pub active_vertices: u64,
    /// Active cells stored.
    #[serde(default)]
    pub active_cells: u64,
    /// Triangles of the extracted mesh.
    #[serde(default)]
    pub output_faces: u64,
    /// Compressed bytes per tensor.
    #[serde(default)]
    pub tensor_bytes: TensorBytes,
    /// Compressed bytes of the four tensors per active vertex.
    #[serde(default)]
    pub bytes_per_active_vertex: f64,
    /// Condition views rendered (`--renders`), and their mean tracing seconds a view.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub render_views: Option<(u32, f64)>,
    /// Peak RSS as the process saw it at its end (`VmHWM`), bytes.
    #[serde(default)]
    pub peak_rss_bytes: Option<u64>,
    /// Wall seconds of the whole subprocess as the driver measured it (start-up included).
    #[serde(default)]
    pub process_seconds: f64,
    /// User CPU seconds of the subprocess (all threads).
    #[serde(default)]
    pub cpu_user_seconds: f64,
    /// System CPU seconds of the subprocess (all threads).
    #[serde(default)]
    pub cpu_sys_seconds: f64,
    /// Peak RSS of the subprocess from the kernel (`ru_maxrss`), bytes; known even when the
    /// process was killed.
    #[serde(default)]
    pub max_rss_bytes: Option<u64>,
}

/// Runs `sparc3d bench-one`: prints one JSON line, exits 0 when the mesh converted. A mesh
/// that fails to load or convert is still a row (`ok: false`, exit 0); only failures of the
/// command itself are errors.
pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mut row = BenchRow {
        path: args.input.display().to_string(),
        resolution: args.resolution.get(),
        ..Default::default()
    };
    if let Err(e) = measure(&args, &mut row) {
        row.ok = false;
        row.error = Some(format!("{e:#}"));
    }
    row.total_seconds = row.stages.iter().map(|(_, s)| s).sum();
    row.peak_rss_bytes = peak_rss_bytes();
    let line = serde_json::to_string(&row).context("serialising the benchmark row")?;
    println!("{line}");
    Ok(ExitCode::SUCCESS)
}

fn measure(args: &Args, row: &mut BenchRow) -> anyhow::Result<()> {
    let name = args.input.display();
    let params = args.measured.conversion.params(args.resolution.get());
    let steps = Steps {
        params: &params,
        input_components: false,
        extract: true,
        samples: None,
        keep_mesh: false,
        encode: Some(Encoding {
            zstd_level: args.measured.zstd_level,
            store_mesh: false,
        }),
        attributes: None,
        quality: false,
        signature: false,
        renders: match args.measured.renders {
            Some(recipe) => Some(render_request(&args.input, recipe)?),
            None => None,
        },
    };
    let done = match convert_file(&args.input, steps) {
        Ok(done) => done,
        Err(failed) => {
            let Failed { error, seconds } = *failed;
            row.stages = seconds.in_order;
            let context = match error {
                StageError::Load(_) => format!("load {name}"),
                StageError::Convert(_) => format!("convert {name} at {}", args.resolution.get()),
                StageError::Samples(_) => format!("sample {name}"),
                StageError::Attributes(_) => format!("read the appearance of {name}"),
                StageError::Renders(_) | StageError::RenderEncode(_) => format!("render {name}"),
                StageError::Encode(_) => format!("encode {name}"),
            };
            return Err(anyhow::Error::new(error).context(context));
        }
    };
    row.stages = done.seconds.in_order;
    row.input_faces = done.input_faces;
    row.input_vertices = done.input_vertices;
    let s = &done.conversion.stats;
    row.active_vertices = s.active_vertices;
    row.active_cells = s.active_cells;
    row.output_faces = done.output_faces.unwrap_or(0);
    let Some(tensors) = done.tensors else {
        anyhow::bail!("encode {name}: the conversion path returned no tensors");
    };
    row.render_views = tensors.renders.as_ref().map(|r| {
        let seconds: f64 = r.views.iter().map(|v| v.seconds).sum();
        (r.views.len() as u32, seconds / r.views.len().max(1) as f64)
    });
    row.tensor_bytes = TensorBytes {
        coords: tensors.coords.blob.len() as u64,
        sdf: tensors.sdf.blob.len() as u64,
        deformation: tensors.deformation.blob.len() as u64,
        cells: tensors.cells.blob.len() as u64,
    };
    row.bytes_per_active_vertex = if row.active_vertices > 0 {
        row.tensor_bytes.total() as f64 / row.active_vertices as f64
    } else {
        0.0
    };
    row.ok = true;
    Ok(())
}

/// The recipe's own views of the file at `path`, seeded as `sparc3d render` seeds it.
fn render_request(
    path: &std::path::Path,
    recipe: sparc3d_render::cond::Recipe,
) -> anyhow::Result<sparc3d_render::cond::Request> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(sparc3d_render::cond::Request {
        recipe,
        views: None,
        size: None,
        seed: crate::commands::render::item_seed(&bytes, 0),
        passes: Default::default(),
    })
}
