//! Column names of a shard row, as constants. docs/FORMAT.md documents each one.

pub mod arrow;
pub mod attributes;
pub mod quality;
pub mod renders;
pub mod signature;
pub mod table;
mod tensors;

/// Position of the item in the frozen manifest (`u64`); rows are sorted by it.
pub const ITEM_INDEX: &str = "item_index";
/// Item id (`utf8`), unique in the job.
pub const ID: &str = "id";
/// Source path or URI (`utf8`).
pub const URI: &str = "uri";
/// sha256 of the source file's bytes (`utf8`, hex), when known.
pub const SOURCE_SHA256: &str = "source_sha256";
/// `ok`, `failed` or `skipped` (`utf8`).
pub const STATUS: &str = "status";
/// Error class of a failed item (`utf8`, null when ok).
pub const ERROR_CLASS: &str = "error_class";
/// Error message of a failed item (`utf8`, null when ok).
pub const ERROR_MESSAGE: &str = "error_message";
/// Last lines of the item's stderr when it failed in its process (`utf8`, nullable).
pub const STDERR_TAIL: &str = "stderr_tail";
/// How many times the item was started (`u32`).
pub const ATTEMPTS: &str = "attempts";
/// Grid resolution N (`u32`).
pub const RESOLUTION: &str = "resolution";
/// Normalization centre, x (`f64`): `unit = (p − center) · scale`.
pub const CENTER_X: &str = "center_x";
/// Normalization centre, y (`f64`).
pub const CENTER_Y: &str = "center_y";
/// Normalization centre, z (`f64`).
pub const CENTER_Z: &str = "center_z";
/// Normalization scale (`f64`).
pub const SCALE: &str = "scale";
/// Input triangles (`u64`).
pub const INPUT_FACES: &str = "input_faces";
/// Input vertices (`u64`).
pub const INPUT_VERTICES: &str = "input_vertices";
/// Input connected components (`u64`, null when not computed).
pub const INPUT_COMPONENTS: &str = "input_components";
/// Active grid vertices stored (`u64`).
pub const ACTIVE_VERTICES: &str = "active_vertices";
/// Active cells stored (`u64`).
pub const ACTIVE_CELLS: &str = "active_cells";
/// Triangles of the extracted mesh (`u64`, null when extraction is off).
pub const OUTPUT_FACES: &str = "output_faces";
/// Vertices treated as thin shell (`u64`).
pub const SHELL_VERTICES: &str = "shell_vertices";
/// Cells touched by the surface (`u64`).
pub const WALL_CELLS: &str = "wall_cells";
/// The shape signature of an ok row (`fixed_size_list<float32>`, null otherwise; absent from
/// shards written before it): near-duplicates have close signatures (`sparc3d dedup`).
pub const SHAPE_SIGNATURE: &str = "shape_signature";
/// The condition views of an ok row of a job with `[renders]` (`list<large_binary>`, an
/// 8-bit RGBA PNG a view in view order; null otherwise, absent from other jobs' shards).
pub const RENDER_VIEWS: &str = "render_views";
/// Seconds spent tracing each view (`list<float64>`, beside [`RENDER_VIEWS`]).
pub const RENDER_SECONDS: &str = "render_seconds";
/// The views' `transforms.json` (`utf8`): cameras in Blender's Z-up world, as the
/// consumer's own render script writes it (docs/RENDERS.md).
pub const RENDER_TRANSFORMS: &str = "render_transforms";
/// What of the source's appearance the views could not draw (`utf8`, one entry a line, empty
/// when all was read; absent from shards written before it): a texture that is missing, or an
/// appearance that could not be read at all (then drawn in the plain grey).
pub const RENDER_NOT_READ: &str = "render_not_read";
/// Seconds loading the file (`f64`).
pub const TIME_LOAD: &str = "time_load_s";
/// Seconds converting (`f64`).
pub const TIME_CONVERT: &str = "time_convert_s";
/// Seconds extracting the mesh (`f64`).
pub const TIME_EXTRACT: &str = "time_extract_s";
/// Seconds encoding the tensors (`f64`).
pub const TIME_ENCODE: &str = "time_encode_s";
/// Seconds for the whole item, as seen by the supervisor (`f64`).
pub const TIME_TOTAL: &str = "time_total_s";
/// Seconds per conversion stage as a JSON object (`utf8`).
pub const TIME_STAGES: &str = "time_stages";

/// Prefix of the provenance columns: a manifest column `license` is stored as the nullable
/// `utf8` column `manifest.license` (docs/FORMAT.md, "Provenance columns").
pub const PROVENANCE_PREFIX: &str = "manifest.";

/// The shard column of the manifest column `name`.
pub fn provenance_column(name: &str) -> String {
    format!("{PROVENANCE_PREFIX}{name}")
}

/// Prefix of every timing column.
pub const TIMING_PREFIX: &str = "time_";

/// Columns whose value depends on the run (timings, attempts, captured stderr); they are
/// excluded from the content digest.
pub fn is_run_dependent(name: &str) -> bool {
    name.starts_with(TIMING_PREFIX) || name == ATTEMPTS || name == STDERR_TAIL
}

/// The sparse-cube and mesh tensors of a row, in column order: name stem (`coords` → columns
/// `coords`, `coords_dtype`, `coords_shape`).
pub const CUBE_TENSORS: [&str; 6] = [
    "coords",
    "sdf",
    "deformation",
    "cells",
    "mesh_vertices",
    "mesh_faces",
];

/// Every tensor stem of a row in column order: [`CUBE_TENSORS`], then the optional
/// vector-set samples ([`SAMPLE_TENSORS`]).
pub fn tensors() -> impl Iterator<Item = &'static str> {
    CUBE_TENSORS.into_iter().chain(SAMPLE_TENSORS)
}

/// Surface samples, `n × 3` floats in the normalized frame (only with `[samples]`).
pub const SURFACE_POINTS: &str = "surface_points";
/// Unit normals of the surface samples, `n × 3`.
pub const SURFACE_NORMALS: &str = "surface_normals";
/// Samples on sharp edges, `m × 3` (`m` is 0 when the mesh has no sharp edge).
pub const SHARP_POINTS: &str = "sharp_points";
/// Edge normals of the sharp samples, `m × 3`.
pub const SHARP_NORMALS: &str = "sharp_normals";
/// Near-surface samples, `q × 3`.
pub const NEAR_POINTS: &str = "near_points";
/// Signed distance of the near samples, `q` (normalized units, negative inside).
pub const NEAR_SDF: &str = "near_sdf";
/// Samples near sharp edges, `r × 3` (`r` is 0 when the mesh has no sharp edge; the column
/// is null in rows of jobs whose config draws none, and absent from shards written before it).
pub const SHARP_NEAR_POINTS: &str = "sharp_near_points";
/// Signed distance of the sharp-near samples, `r` (normalized units, negative inside).
pub const SHARP_NEAR_SDF: &str = "sharp_near_sdf";
/// Volume samples, `p × 3`.
pub const VOLUME_POINTS: &str = "volume_points";
/// Signed distance of the volume samples, `p`.
pub const VOLUME_SDF: &str = "volume_sdf";
/// Occupancy of the volume samples, `p` bytes (1 inside).
pub const VOLUME_OCCUPANCY: &str = "volume_occupancy";

/// The sample tensors, in column order: the ones every row with samples has, then
/// [`OPTIONAL_SAMPLE_TENSORS`] (last, so the columns of earlier shards keep their places).
pub const SAMPLE_TENSORS: [&str; 11] = [
    SURFACE_POINTS,
    SURFACE_NORMALS,
    SHARP_POINTS,
    SHARP_NORMALS,
    NEAR_POINTS,
    NEAR_SDF,
    VOLUME_POINTS,
    VOLUME_SDF,
    VOLUME_OCCUPANCY,
    SHARP_NEAR_POINTS,
    SHARP_NEAR_SDF,
];

/// The sample tensors of kinds added after the schema's first shards: a row with samples may
/// lack them (its job draws none), and a shard written before them has no such column; both
/// read as absent.
pub const OPTIONAL_SAMPLE_TENSORS: [&str; 2] = [SHARP_NEAR_POINTS, SHARP_NEAR_SDF];

/// Base colour of each active cell, `m × 3` `<u1`, sRGB, one row per row of `cells` (only
/// with `[attributes]`).
pub const BASE_COLOR: &str = "base_color";
/// Metallic of each active cell, `m` `<u1` (0–255 for 0–1).
pub const METALLIC: &str = "metallic";
/// Roughness of each active cell, `m` `<u1` (0–255 for 0–1).
pub const ROUGHNESS: &str = "roughness";
/// Alpha (coverage) of each active cell, `m` `<u1` (0–255 for 0–1).
pub const ALPHA: &str = "alpha";

/// The attribute tensors, in column order: present in the shards of a job with
/// `[attributes] enabled = true` only, after the sample tensors.
pub const ATTRIBUTE_TENSORS: [&str; 4] = [BASE_COLOR, METALLIC, ROUGHNESS, ALPHA];

/// Materials the source defines and uses (`u32`; only with `[attributes]`).
pub const MATERIALS: &str = "materials";
/// Whether any texture was read (`bool`).
pub const TEXTURED: &str = "textured";
/// Textures read and used (`u32`).
pub const TEXTURES: &str = "textures";
/// Largest side of those textures in pixels (`u32`, 0 without any).
pub const TEXTURE_MAX_SIZE: &str = "texture_max_size";
/// Alpha modes of the materials used (`utf8`, comma-separated glTF names, sorted).
pub const ALPHA_MODES: &str = "alpha_modes";
/// Whether the source has vertex colours (`bool`).
pub const VERTEX_COLORS: &str = "vertex_colors";
/// Features of the source's appearance that were not read (`utf8`, one per line, sorted).
pub const APPEARANCE_NOT_READ: &str = "appearance_not_read";
/// Active cells no source triangle crosses, which took the closest surface point's values
/// (`u64`).
pub const NEAREST_CELLS: &str = "attribute_nearest_cells";

/// Name of a tensor's dtype column.
pub fn dtype_column(tensor: &str) -> String {
    format!("{tensor}_dtype")
}

/// Name of a tensor's shape column.
pub fn shape_column(tensor: &str) -> String {
    format!("{tensor}_shape")
}

// Quality columns (docs/FORMAT.md, "Quality columns"; only in jobs with `quality = true`).

/// Edges of the welded source used by one triangle (`u64`): holes and open borders.
pub const INPUT_BOUNDARY_EDGES: &str = "input_boundary_edges";
/// Edges of the welded source used by more than two triangles (`u64`).
pub const INPUT_NON_MANIFOLD_EDGES: &str = "input_non_manifold_edges";
/// Source triangles of zero area (`u64`).
pub const INPUT_DEGENERATE_FACES: &str = "input_degenerate_faces";
/// Source triangles dropped at load for repeating an earlier one (`u64`).
pub const INPUT_DUPLICATE_FACES: &str = "input_duplicate_faces";
/// Extent of the source's bounding box along x, in its units (`f64`).
pub const EXTENT_X: &str = "extent_x";
/// Extent along y (`f64`).
pub const EXTENT_Y: &str = "extent_y";
/// Extent along z (`f64`).
pub const EXTENT_Z: &str = "extent_z";
/// Longest extent over shortest (`f64`, `inf` for a flat source).
pub const ASPECT: &str = "aspect";
/// Surface area of the source, in its units squared (`f64`).
pub const SURFACE_AREA: &str = "surface_area";
/// Volume enclosed by the output mesh, in the source's units cubed (`f64`, null when the mesh
/// is not extracted).
pub const OUTPUT_VOLUME: &str = "output_volume";
/// `shell_vertices / active_vertices` (`f64`): how much of the output is thin shell.
pub const SHELL_SHARE: &str = "shell_share";
/// Regions sealed behind small openings and kept solid (`u64`).
pub const SEALED_POCKETS: &str = "sealed_pockets";
/// Connected components of the output mesh (`u64`, null when the mesh is not extracted).
pub const OUTPUT_COMPONENTS: &str = "output_components";
