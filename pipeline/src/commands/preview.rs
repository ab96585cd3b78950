//! `sparc3d preview (MESH | JOB --id X) -o x.png`: a shaded ray-cast picture of a source mesh
//! (top row, labelled SOURCE) and its converted output (bottom row, OUTPUT), from a few
//! views, so a broken conversion is seen at a glance. Back faces are red: red in the top row is an open or inverted source,
//! red in the bottom row a broken output.
//!
//! In colour when there are colours (unless `--no-colours`): a mesh whose source has
//! materials, textures or vertex colours is drawn in them above its output coloured as
//! `convert --attributes` colours it; a job's item stored with attributes likewise. Other
//! pictures are the plain grey-blue ones.
//!
//! With a mesh, it is converted here (like `sparc3d convert`); with a job and an item id, the
//! item's row is decoded (as `sparc3d show` does) and the source is loaded from the row's uri.

use crate::check::pictures::{preview_mesh, preview_row, write_png};
use crate::rows::item_lookup;
use anyhow::{bail, Result};
use sparc3d_render::CompareOptions;
use std::path::PathBuf;
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
    pub resolution: crate::flags::resolution::ResolutionArg,
    /// A mesh is converted with the inside test on unless `--no-inside-test` (as `convert`;
    /// docs/ALGORITHM.md §6). Neither flag applies to a job's item, drawn as the job made it.
    #[command(flatten)]
    pub inside_test: crate::flags::inside_test::InsideTestArgs,
    /// A mesh is refined against renderings of its source when `--refine` (as `convert`;
    /// docs/ALGORITHM.md §12), so a before/after pair is two calls. A job's item is drawn as
    /// the job stored it (refined when its job refines).
    #[command(flatten)]
    pub refine: crate::flags::refine::RefineArgs,
    /// Draw the plain grey-blue pictures even when the source has colours (materials,
    /// textures, vertex colours) or the item stored attributes.
    #[arg(long)]
    pub no_colours: bool,
}

/// The conversion parameters of a mesh drawn by `preview`: its resolution and rules.
fn rules(args: &Args) -> sparcubes::Params {
    let mut params = sparcubes::Params::with_resolution(args.resolution.get());
    args.inside_test.apply_to(&mut params);
    params.refine = args.refine.settings();
    params
}

/// Runs `sparc3d preview`.
pub fn run(args: Args) -> Result<ExitCode> {
    let options = CompareOptions {
        views: args.views,
        tile: args.tile,
        elevation_deg: args.elevation,
    };
    let (image, what) = match &args.id {
        Some(_) if args.inside_test.given() || args.refine.refine => {
            bail!(
                "--inside-test, --no-inside-test, --no-seal-openings and --refine apply to a \
                 mesh; a job's item is drawn as the job made it"
            )
        }
        Some(id) => {
            let job = crate::job::setup::open_read_only(&args.input)?;
            let row = item_lookup::row(&job, &item_lookup::find(&job, id)?)?;
            (
                preview_row(&row, &options, !args.no_colours)?,
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
            let params = rules(&args);
            super::check_params(&params)?;
            (
                preview_mesh(&args.input, &params, &options, !args.no_colours)?,
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
