//! The pictures `preview` and `report` draw: a source mesh above its converted output, from a
//! few views, each row labelled; and writing them as PNG.
//!
//! In colour when there are colours to show: a mesh whose source carries materials, textures
//! or vertex colours, or a job's item stored with attributes (`[attributes]`). The source row
//! then shows its own appearance (its surface as the attribute sampler reads it), the output
//! row each vertex in its cell's base colour, as `convert --attributes` writes the mesh.
//! Anything else is drawn in the plain grey-blue, byte for byte as before colours existed.

use crate::rows::item_lookup;
use anyhow::{Context, Result};
use sparc3d_render::paint::{Paint, SurfaceColours, VertexColours};
use sparc3d_render::{compare_painted, CompareOptions, Drawn, Image};
use sparc3d_schema::ShardRow;
use sparcubes::attributes::CellAttributes;
use sparcubes::materials::Appearance;
use sparcubes::{SparseCubes, TriMesh};
use std::path::Path;

/// Converts the mesh at `path` with `params` and renders source above output, in colour when
/// `colours` and the source has any.
pub fn preview_mesh(
    path: &Path,
    params: &sparcubes::Params,
    options: &CompareOptions,
    colours: bool,
) -> Result<Image> {
    let source = load(path)?;
    let conversion = sparcubes::convert(&source, params)
        .with_context(|| format!("converting {}", path.display()))?;
    let cubes = &conversion.cubes;
    let appearance = if colours {
        coloured(appearance_of_file(path), &path.display().to_string())
    } else {
        None
    };
    let cells = appearance
        .as_ref()
        .map(|a| sparcubes::attributes::sample(cubes, a));
    Ok(draw(
        &source,
        appearance.as_ref(),
        cubes,
        cells.as_ref(),
        options,
    ))
}

/// Decodes a row's cubes, extracts them in the source frame, loads the source from the row's
/// uri, and renders source above output; in colour when `colours` and the row stores
/// attributes.
pub fn preview_row(row: &ShardRow, options: &CompareOptions, colours: bool) -> Result<Image> {
    let cubes = item_lookup::cubes(row)?;
    let stored = row.tensors.as_ref().and_then(|t| t.attributes.as_ref());
    let cells = match stored.filter(|_| colours) {
        Some(a) => Some(
            a.to_attributes()
                .with_context(|| format!("decoding the attributes of {}", row.id))?,
        ),
        None => None,
    };
    let source = sparc3d_workers::item::source::load_mesh(&row.uri)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("loading the source of item {:?}", row.id))?
        .mesh;
    let appearance = cells
        .as_ref()
        .and_then(|_| coloured(appearance_of_uri(&row.uri), &row.uri));
    Ok(draw(
        &source,
        appearance.as_ref(),
        &cubes,
        cells.as_ref(),
        options,
    ))
}

/// The appearance when it carries colours to show (materials, textures or vertex colours);
/// none, with a note naming `what`, when it could not be read.
pub(crate) fn coloured(read: Result<Appearance>, what: &str) -> Option<Appearance> {
    match read {
        Ok(a) => sparc3d_render::cond::asset::with_colours(a),
        Err(e) => {
            eprintln!("note: {what} is drawn without its colours: {e:#}");
            None
        }
    }
}

/// Extracts `cubes` and draws `source` above the output: each row in colour when it has
/// them (the source its `appearance`, the output its `cells`' colours), else plain.
fn draw(
    source: &TriMesh,
    appearance: Option<&Appearance>,
    cubes: &SparseCubes,
    cells: Option<&CellAttributes>,
    options: &CompareOptions,
) -> Image {
    let mut output = sparcubes::extract(cubes);
    let colours =
        cells.map(|c| sparcubes::attributes::vertex_colours::vertex_colours(cubes, c, &output));
    sparcubes::extract::to_source(&mut output, &cubes.normalization, cubes.resolution);
    // The source drawn in colour is the surface its appearance was read on, so that its
    // triangle numbers are the appearance's.
    let surface =
        appearance.map(|a| TriMesh::new(a.surface.positions.clone(), a.surface.triangles.clone()));
    let source = surface.as_ref().unwrap_or(source);
    let bounds = sparc3d_render::union_bounds([source, &output].into_iter());
    let pixel = sparc3d_render::pixel_size(bounds, options);
    let source_paint = appearance.map(|a| SurfaceColours::new(a, pixel));
    let output_paint = colours.as_ref().map(|colours| VertexColours {
        triangles: &output.triangles,
        colours,
    });
    let rows = [
        Drawn {
            mesh: source,
            paint: source_paint.as_ref().map(|p| p as &dyn Paint),
        },
        Drawn {
            mesh: &output,
            paint: output_paint.as_ref().map(|p| p as &dyn Paint),
        },
    ];
    let mut image = compare_painted(&rows, options);
    if options.tile >= 64 {
        let scale = (options.tile / 128).clamp(1, 3);
        // Rows are `tile` high with a 2-pixel line between them (`compare`).
        for (row, text) in [(0, "SOURCE"), (1, "OUTPUT")] {
            sparc3d_render::label::draw(&mut image, 4, row * (options.tile + 2) + 4, text, scale);
        }
    }
    image
}

/// The appearance of the mesh file at `path`, its images and material libraries beside it.
pub(crate) fn appearance_of_file(path: &Path) -> Result<Appearance> {
    let bytes =
        sparcubes::io::read_source(path).with_context(|| format!("reading {}", path.display()))?;
    sparcubes::materials::read(&bytes, path, sparcubes::io::Buffers::Folder)
        .with_context(|| format!("reading the appearance of {}", path.display()))
}

/// The appearance of an item's source at `uri`: a local file, or a remote object whose
/// images and buffers are read from its own prefix.
fn appearance_of_uri(uri: &str) -> Result<Appearance> {
    use sparc3d_sources::Location;
    use sparc3d_workers::item::source::{fetcher, RemoteBuffers};
    match Location::parse(uri)? {
        Location::Local(path) => appearance_of_file(&path),
        Location::Remote(url) => {
            let fetched = fetcher()
                .and_then(|f| f.fetch(&url, None))
                .with_context(|| format!("fetching {uri}"))?;
            let buffers = RemoteBuffers::new(url.clone());
            let read = |relative: &str| buffers.read(relative);
            let path = std::path::PathBuf::from(url.to_string());
            let relative = sparcubes::io::Buffers::Relative(&read);
            sparcubes::materials::read(&fetched.bytes, &path, relative)
                .with_context(|| format!("reading the appearance of {uri}"))
        }
    }
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
