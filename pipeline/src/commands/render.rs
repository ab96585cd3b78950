//! `sparc3d render MESH -o DIR [--for trellis|trellis2] [--passes normal,depth,albedo,mask]`:
//! the condition views of one asset as the consumer's own Blender script would lay them out
//! (`000.png …` RGBA, `NNN_<pass>.png` beside them, and `transforms.json`), traced on the CPU (`sparc3d_render::cond`, docs/RENDERS.md). The
//! cameras' random draws are seeded from the file's sha256 (and `--seed`), so the same file
//! gives the same bytes.

use anyhow::{bail, Context, Result};
use sparc3d_render::cond::passes::{Pass, PassSet};
use sparc3d_render::cond::{asset, Recipe, Request};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `sparc3d render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A mesh (OBJ, PLY, STL, OFF, glTF, GLB).
    pub input: PathBuf,
    /// Folder to write the views and `transforms.json` into (made if missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Whose cameras, view count, size and lights: `trellis` (24 views, three lights) or
    /// `trellis2` (16 views, a white world and random point lights).
    #[arg(long = "for", default_value = "trellis2", value_parser = parse_recipe)]
    pub recipe: Recipe,
    /// Views (default: the recipe's).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub views: Option<u32>,
    /// Side of a view in pixels (default: the recipe's, 1024).
    #[arg(long, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub size: Option<u32>,
    /// Mixed into the seed the file's sha256 gives: another set of random views.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Draw the plain grey surface even when the source has colours.
    #[arg(long)]
    pub no_colours: bool,
    /// Passes to write beside each view, comma-separated: `normal` (16-bit RGBA of
    /// (n + 1)/2, Blender's Z-up world), `depth` (16-bit grey over the frame's `depth` range
    /// in transforms.json), `albedo` (base colour before lighting, RGBA), `mask` (alpha as
    /// grey); files `NNN_<pass>.png` as TRELLIS's render script names them.
    #[arg(long, value_delimiter = ',', value_parser = parse_pass)]
    pub passes: Vec<Pass>,
}

/// A pass a flag names; the error lists them.
fn parse_pass(name: &str) -> std::result::Result<Pass, String> {
    Pass::named(name).ok_or_else(|| {
        let known: Vec<&str> = Pass::ALL.iter().map(|(n, _)| *n).collect();
        format!("no render pass {name:?}: one of {}", known.join(", "))
    })
}

/// The render recipe a flag names (`trellis`, `trellis2`); the error lists them.
pub fn parse_recipe(name: &str) -> std::result::Result<Recipe, String> {
    Recipe::named(name).ok_or_else(|| {
        let known: Vec<&str> = Recipe::ALL.iter().map(|(n, _)| *n).collect();
        format!("no render recipe {name:?}: one of {}", known.join(", "))
    })
}

/// The seed of a source: the first 8 bytes of its sha256, mixed with `extra`.
pub fn item_seed(bytes: &[u8], extra: u64) -> u64 {
    use sha2::{Digest, Sha256};
    let digest = Sha256::digest(bytes);
    let mut head = [0u8; 8];
    head.copy_from_slice(&digest[..8]);
    asset::seed_of(head, extra)
}

/// Runs `sparc3d render`.
pub fn run(args: Args) -> Result<ExitCode> {
    let path = &args.input;
    let bytes =
        sparcubes::io::read_source(path).with_context(|| format!("reading {}", path.display()))?;
    let mesh = sparcubes::io::load_read(&bytes, path)
        .with_context(|| format!("loading {}", path.display()))?
        .mesh;
    let appearance = match args.no_colours {
        true => None,
        false => crate::pictures::coloured(
            sparcubes::materials::read(&bytes, path, sparcubes::io::Buffers::Folder)
                .with_context(|| format!("reading the appearance of {}", path.display())),
            &path.display().to_string(),
        ),
    };
    let request = Request {
        recipe: args.recipe,
        views: args.views,
        size: args.size,
        seed: item_seed(&bytes, args.seed),
        passes: PassSet::of(&args.passes),
    };
    let views = asset::render_asset(&mesh, appearance.as_ref(), &request)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    write(&args.output, &views)?;
    let total: f64 = views.seconds.iter().sum();
    eprintln!(
        "{}: {} views of {}² in {:.2} s ({:.3} s a view) written to {}",
        path.display(),
        views.pngs.len(),
        views.size,
        total,
        total / views.pngs.len().max(1) as f64,
        args.output.display()
    );
    if !views.empty.is_empty() {
        bail!(
            "{}: {} views see nothing of the asset",
            path.display(),
            views.empty.len()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Writes `NNN.png` for each view and `transforms.json`, each file atomically.
fn write(dir: &std::path::Path, views: &asset::AssetViews) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (i, png) in views.pngs.iter().enumerate() {
        let file = dir.join(format!("{i:03}.png"));
        sparc3d_workers::fsutil::write_atomic(&file, png, "writing a view")?;
        for (pass, png) in views.passes.get(i).into_iter().flatten() {
            let file = dir.join(pass.file_name(i));
            sparc3d_workers::fsutil::write_atomic(&file, png, "writing a pass")?;
        }
    }
    let file = dir.join("transforms.json");
    sparc3d_workers::fsutil::write_atomic(
        &file,
        views.transforms.as_bytes(),
        "writing transforms.json",
    )?;
    Ok(())
}
