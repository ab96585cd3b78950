//! `sparc3d export JOB --format F --out DIR [--ids …] [--frame source|normalized]`: writes one
//! `.npz` per ok item in another codebase's on-disk layout (docs/FORMAT.md, "Exports"). The
//! sparse layouts are computed from the stored grid by `sparcubes::layouts`; the vector-set
//! samples come from the shard's sample columns. Every file carries the item it holds (`id`,
//! `item_index`) and its normalization (`center`, `scale`, `resolution`); file names come from
//! `export_name` (unique per item, within the file-name limit).

use crate::export_name::{self, ExportNames};
use crate::item_lookup;
use crate::npz::{self, npz_bytes, Array};
use anyhow::{bail, Context, Result};
use sparc3d_schema::ShardRow;
use sparc3d_workers::store::read::shard_rows;
use sparc3d_workers::store::state::Check;
use sparc3d_workers::Job;
use sparcubes::layouts::{cubvh, direct3d_s2, trellis2};
use sparcubes::samples::Precision;
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The layouts `export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Vector-set VAE samples (surface, sharp, near, volume) from the sample columns.
    VecsetNpz,
    /// Direct3D-S2's sparse SDF: `sparse_index`, `sparse_sdf`.
    Direct3dS2,
    /// TRELLIS.2's flexible dual grid in o_voxel's npz layout: `coord`, `vertices`,
    /// `intersected`.
    Trellis2,
    /// cubvh's sparse voxels: `active_cells`, `active_cells_sdf` (packed u64).
    Cubvh,
}

/// The frame of exported sample coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Frame {
    /// The source mesh's frame (as `convert` and `show` write meshes).
    Source,
    /// The job's normalized frame, [−1, 1]³ (`p = 2·(source − center)·scale`).
    Normalized,
}

/// Arguments of `sparc3d export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Job folder.
    pub job: PathBuf,
    /// Layout to write.
    #[arg(long, value_enum)]
    pub format: Format,
    /// Output folder (created); one `<index>-<id>.npz` per item (docs/FORMAT.md, "Exports").
    #[arg(long)]
    pub out: PathBuf,
    /// Only these items (comma-separated or repeated), each named as `--id` elsewhere: its id,
    /// a unique prefix of it, or its source file (path or file name); default: every ok item.
    #[arg(long, value_delimiter = ',')]
    pub ids: Vec<String>,
    /// Frame of sample coordinates and distances (vecset-npz only).
    #[arg(long, value_enum, default_value = "source")]
    pub frame: Frame,
}

/// Runs `sparc3d export`.
pub fn run(args: Args) -> Result<ExitCode> {
    let job = Job::open(&args.job)?;
    let samples_on = job.file.config.samples.enabled;
    if args.format == Format::VecsetNpz && !samples_on {
        bail!(
            "{}: the job has no samples (config key samples.enabled is false); \
             vecset-npz needs a job initialised with `[samples] enabled = true`",
            args.job.display()
        );
    }
    // Each `--ids` entry names an item as `--id` does elsewhere (whole id, unique prefix or
    // source file); a miss fails before anything is written, with the closest names.
    let mut wanted: BTreeSet<&str> = BTreeSet::new();
    for query in &args.ids {
        wanted.insert(item_lookup::find(&job, query)?.record.id.as_str());
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let shards: BTreeSet<u64> = job
        .items
        .iter()
        .filter(|i| wanted.is_empty() || wanted.contains(i.record.id.as_str()))
        .map(|i| i.shard)
        .collect();
    let dtype = job.file.config.samples.params.dtype;
    let names = ExportNames::for_job(job.file.items);
    let (mut written, mut failed) = (0u64, 0u64);
    for shard in shards {
        for row in shard_rows(&job, shard, Check::Full)? {
            if !(wanted.is_empty() || wanted.contains(row.id.as_str())) || row.tensors.is_none() {
                continue;
            }
            let name = names.file_name(row.item_index, &row.id, "npz");
            match export_row(&row, args.format, args.frame, dtype)
                .and_then(|arrays| write_item_file(&args.out, &name, &row.id, &npz_bytes(&arrays)?))
            {
                Ok(()) => written += 1,
                Err(e) => {
                    failed += 1;
                    eprintln!("error: item {:?}: {e:#}", row.id);
                }
            }
        }
    }
    // The renames last, once: the files were fsynced one by one.
    if written > 0 {
        sparc3d_workers::fsutil::sync_dir(&args.out)?;
    }
    eprintln!(
        "{written} items written to {}{}",
        args.out.display(),
        if failed > 0 {
            format!(", {failed} failed")
        } else {
            String::new()
        }
    );
    Ok(if failed > 0 {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    })
}

/// Writes item `id`'s file `name` in `dir`: to a temporary name, fsynced, then renamed. A
/// file already there is replaced only when it holds the same item (a second export of the
/// job); one that holds another item, or that is not an export at all, is an error and stays.
fn write_item_file(dir: &Path, name: &str, id: &str, bytes: &[u8]) -> Result<()> {
    let path = dir.join(name);
    refuse_another_items_file(&path, id)?;
    let tmp = dir.join(export_name::tmp_name(name));
    let written = (|| -> Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        Ok(std::fs::rename(&tmp, &path)?)
    })()
    .with_context(|| format!("writing {} (through {})", path.display(), tmp.display()));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

/// An error when `path` exists and holds anything but item `id`'s export.
fn refuse_another_items_file(path: &Path, id: &str) -> Result<()> {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("reading {}", path.display())),
    };
    match npz::read_text(&bytes, "id") {
        Some(found) if found == id => Ok(()),
        Some(found) => bail!(
            "{} already holds item {found:?} (another job's export?); not overwritten: \
             export into an empty folder",
            path.display()
        ),
        None => bail!(
            "{} already exists and is not an export of an item (no `id` entry); not \
             overwritten: export into an empty folder",
            path.display()
        ),
    }
}

/// The vector-set samples of one item (points, normals, signed distances, occupancy) in
/// `frame`, with the frame's name; distances scale with the frame.
fn vecset_arrays(
    row: &ShardRow,
    norm: &sparcubes::Normalization,
    frame: Frame,
    dtype: Precision,
) -> Result<Vec<Array>> {
    let Some(t) = row.tensors.as_ref().and_then(|t| t.samples.as_ref()) else {
        bail!("no sample columns (config key samples.enabled was off when it converted)");
    };
    let s = t.to_samples()?;
    // Normalized p = 2·(source − center)·scale: source = p·k + center with
    // k = 1 / (2·scale), and distances scale by k.
    let (k, offset) = match frame {
        Frame::Normalized => (1.0, [0.0; 3]),
        Frame::Source => (1.0 / (2.0 * norm.scale), norm.center),
    };
    let to_point =
        |p: [f32; 3]| -> [f32; 3] { std::array::from_fn(|a| (p[a] as f64 * k + offset[a]) as f32) };
    let dist = k;
    // The source frame is written as f32 (its coordinates may not fit f16 well).
    let descr = match (frame, dtype) {
        (Frame::Normalized, Precision::F16) => "<f2",
        _ => "<f4",
    };
    let floats = |name: &str, shape: Vec<usize>, v: Vec<f32>| -> Array {
        if descr == "<f2" {
            let h: Vec<u16> = v
                .iter()
                .map(|&x| half::f16::from_f32(x).to_bits())
                .collect();
            Array::numbers(name, descr, shape, &h)
        } else {
            Array::numbers(name, descr, shape, &v)
        }
    };
    let points = |name: &str, v: &[[f32; 3]]| {
        floats(
            name,
            vec![v.len(), 3],
            v.iter().flat_map(|p| to_point(*p)).collect(),
        )
    };
    let vectors = |name: &str, v: &[[f32; 3]]| {
        floats(
            name,
            vec![v.len(), 3],
            v.iter().flatten().copied().collect(),
        )
    };
    let distances = |name: &str, v: &[f32]| {
        floats(
            name,
            vec![v.len()],
            v.iter().map(|&d| (d as f64 * dist) as f32).collect(),
        )
    };
    let mut arrays = vec![
        points("surface_points", &s.surface_points),
        vectors("surface_normals", &s.surface_normals),
        points("sharp_points", &s.sharp_points),
        vectors("sharp_normals", &s.sharp_normals),
        points("near_points", &s.near_points),
        distances("near_sdf", &s.near_sdf),
        points("volume_points", &s.volume_points),
        distances("volume_sdf", &s.volume_sdf),
        Array::numbers(
            "volume_occupancy",
            "|u1",
            vec![s.volume_occupancy.len()],
            &s.volume_occupancy,
        ),
    ];
    // Only where the job draws them (not in jobs from before the kind existed).
    if t.sharp_near.is_some() {
        arrays.extend([
            points("sharp_near_points", &s.sharp_near_points),
            distances("sharp_near_sdf", &s.sharp_near_sdf),
        ]);
    }
    arrays.push(Array::text(
        "frame",
        match frame {
            Frame::Source => "source",
            Frame::Normalized => "normalized",
        },
    ));
    Ok(arrays)
}

/// The arrays of one item in `format`.
fn export_row(
    row: &ShardRow,
    format: Format,
    frame: Frame,
    dtype: Precision,
) -> Result<Vec<Array>> {
    let cubes = row.cubes()?;
    let norm = cubes.normalization;
    let n = cubes.resolution as usize;
    let mut arrays = vec![
        Array::text("id", &row.id),
        Array::numbers("item_index", "<i8", vec![], &[row.item_index as i64]),
        Array::numbers("center", "<f8", vec![3], &norm.center),
        Array::numbers("scale", "<f8", vec![], &[norm.scale]),
        Array::numbers("resolution", "<i8", vec![], &[n as i64]),
    ];
    match format {
        Format::VecsetNpz => arrays.extend(vecset_arrays(row, &norm, frame, dtype)?),
        Format::Direct3dS2 => {
            let s = direct3d_s2::sparse_sdf(&cubes, direct3d_s2::TRUNCATION);
            let index: Vec<i32> = s.coords.iter().flatten().map(|&c| c as i32).collect();
            arrays.extend([
                Array::numbers("sparse_index", "<i4", vec![s.coords.len(), 3], &index),
                Array::numbers("sparse_sdf", "<f4", vec![s.sdf.len(), 1], &s.sdf),
            ]);
        }
        Format::Trellis2 => {
            let g = trellis2::dual_grid(&cubes);
            let coord: Vec<u16> = g.voxels.iter().flatten().copied().collect();
            let vertices: Vec<u8> = g.quantized.iter().flatten().copied().collect();
            arrays.extend([
                Array::numbers("coord", "<u2", vec![g.voxels.len(), 3], &coord),
                Array::numbers("vertices", "|u1", vec![g.voxels.len(), 3], &vertices),
                Array::numbers(
                    "intersected",
                    "|u1",
                    vec![g.voxels.len(), 1],
                    &g.intersected,
                ),
            ]);
        }
        Format::Cubvh => {
            let v = cubvh::cubvh_voxels(&cubes);
            let n = n as u64;
            let cells: Vec<u64> = v
                .cells
                .iter()
                .map(|c| (c[0] as u64 * n + c[1] as u64) * n + c[2] as u64)
                .collect();
            let codes: Vec<u64> = v.codes.iter().map(|c| u64::from_le_bytes(*c)).collect();
            arrays.extend([
                Array::numbers("active_cells", "<u8", vec![cells.len()], &cells),
                Array::numbers("active_cells_sdf", "<u8", vec![codes.len()], &codes),
            ]);
        }
    }
    Ok(arrays)
}
