//! The pictures `preview` and `report` draw: a source mesh above its converted output, from a
//! few views, each row labelled; and writing them as PNG.

use crate::item_lookup;
use anyhow::{Context, Result};
use sparc3d_render::{compare, CompareOptions, Image};
use sparc3d_schema::ShardRow;
use sparcubes::TriMesh;
use std::path::Path;

/// Converts the mesh at `path` with `params` and renders source above output.
pub fn preview_mesh(
    path: &Path,
    params: &sparcubes::Params,
    options: &CompareOptions,
) -> Result<Image> {
    let source = load(path)?;
    let conversion = sparcubes::convert(&source, params)
        .with_context(|| format!("converting {}", path.display()))?;
    let output = sparcubes::extract::extract_to_source(&conversion.cubes);
    Ok(source_above_output(&source, &output, options))
}

/// Decodes a row's cubes, extracts them in the source frame, loads the source from the row's
/// uri, and renders source above output.
pub fn preview_row(row: &ShardRow, options: &CompareOptions) -> Result<Image> {
    let cubes = item_lookup::cubes(row)?;
    let output = sparcubes::extract::extract_to_source(&cubes);
    let source = sparc3d_workers::source::load_mesh(&row.uri)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("loading the source of item {:?}", row.id))?
        .mesh;
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
