//! `sparc3d preview (MESH | JOB --id X) -o x.png`: a shaded ray-cast picture of a source mesh
//! (top row, labelled SOURCE) and its converted output (bottom row, OUTPUT), from a few
//! views, so a broken conversion is seen at a glance. Back faces are red: red in the top row is an open or inverted source,
//! red in the bottom row a broken output.
//!
//! With a mesh, it is converted here (like `sparc3d convert`); with a job and an item id, the
//! item's row is decoded (as `sparc3d show` does) and the source is loaded from the row's uri.

use crate::item_lookup;
use anyhow::{bail, Context, Result};
use sparc3d_render::{compare, CompareOptions, Image};
use sparc3d_schema::ShardRow;
use sparc3d_workers::Job;
use sparcubes::TriMesh;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `sparc3d preview`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A mesh (OBJ, PLY, STL, OFF, glTF, GLB), or a job folder with `--id`.
    pub input: PathBuf,
    /// Item, when INPUT is a job folder: its id, a unique prefix of it, or its source file's
    /// path or name (`sparc3d ls JOB` lists the items).
    #[arg(long)]
    pub id: Option<String>,
    /// Output picture (PNG).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Views per mesh, evenly spaced around the vertical axis.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=16))]
    pub views: u32,
    /// Side of one view in pixels.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=2048))]
    pub tile: u32,
    /// Camera elevation in degrees.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub elevation: f32,
    #[command(flatten)]
    pub resolution: crate::resolution_arg::ResolutionArg,
}

/// Runs `sparc3d preview`.
pub fn run(args: Args) -> Result<ExitCode> {
    let options = CompareOptions {
        views: args.views,
        tile: args.tile,
        elevation_deg: args.elevation,
    };
    let (image, what) = match &args.id {
        Some(id) => {
            let job = Job::open(&args.input)?;
            let row = item_lookup::row(&job, item_lookup::find(&job, id)?)?;
            (
                preview_row(&row, &options)?,
                format!("item {} ({})", row.id, row.uri),
            )
        }
        None => {
            if args.input.is_dir() {
                bail!(
                    "{} is a folder: give a mesh, or a job folder with --id",
                    args.input.display()
                );
            }
            (
                preview_mesh(&args.input, args.resolution.get(), &options)?,
                args.input.display().to_string(),
            )
        }
    };
    write_png(&image, &args.output)?;
    eprintln!(
        "{what}: source (top) and output (bottom), {} views, written to {}",
        args.views,
        args.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

/// Converts the mesh at `path` at `resolution` and renders source above output.
pub fn preview_mesh(path: &Path, resolution: u32, options: &CompareOptions) -> Result<Image> {
    let source = load(path)?;
    let params = sparcubes::Params::with_resolution(resolution);
    let conversion = sparcubes::convert(&source, &params)
        .with_context(|| format!("converting {}", path.display()))?;
    let output = sparcubes::extract::extract_to_source(&conversion.cubes);
    Ok(source_above_output(&source, &output, options))
}

/// Decodes a row's cubes, extracts them in the source frame, loads the source from the row's
/// uri, and renders source above output.
pub fn preview_row(row: &ShardRow, options: &CompareOptions) -> Result<Image> {
    let cubes = row.cubes().with_context(|| {
        format!(
            "item {:?}: {}",
            row.id,
            row.error_message.clone().unwrap_or_default()
        )
    })?;
    let output = sparcubes::extract::extract_to_source(&cubes);
    let source = load(Path::new(&row.uri))
        .with_context(|| format!("loading the source of item {:?}", row.id))?;
    Ok(source_above_output(&source, &output, options))
}

/// Renders `source` above `output`, each row labelled in its top-left corner (when the
/// tiles are large enough to hold the label).
fn source_above_output(source: &TriMesh, output: &TriMesh, options: &CompareOptions) -> Image {
    let mut image = compare(&[source, output], options);
    if options.tile >= 64 {
        let scale = (options.tile / 128).clamp(1, 3);
        // Rows are `tile` high with a 2-pixel line between them (`compare`).
        for (row, text) in [(0, "SOURCE"), (1, "OUTPUT")] {
            sparc3d_render::label::draw(&mut image, 4, row * (options.tile + 2) + 4, text, scale);
        }
    }
    image
}

/// Loads a mesh, naming the file in the error.
fn load(path: &Path) -> Result<TriMesh> {
    Ok(sparcubes::io::load(path)
        .with_context(|| format!("loading {}", path.display()))?
        .mesh)
}

/// Writes a picture as PNG.
pub fn write_png(image: &Image, path: &Path) -> Result<()> {
    let bytes = image.encode_png().context("encoding PNG")?;
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}
