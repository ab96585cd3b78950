//! One shard row in memory: an item's outcome, counts, timings and encoded tensors.

pub mod class;
pub mod digest;
pub mod quality;
pub mod tensor;

use crate::columns as c;
use crate::error::{Result, SchemaError};
use crate::job::manifest::FrozenItem;
use crate::row::class::{ErrorClass, ItemStatus};
use crate::row::tensor::{DType, EncodedTensor};
use serde::{Deserialize, Serialize};
use sparcubes::attributes::CellAttributes;
use sparcubes::materials::Facts;
use sparcubes::samples::{Precision, SampleParams, Samples};
use sparcubes::{Normalization, SparseCubes};
use std::collections::BTreeMap;

/// Counts of an ok item.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RowCounts {
    /// Input triangles.
    pub input_faces: u64,
    /// Input vertices.
    pub input_vertices: u64,
    /// Input connected components, when computed.
    pub input_components: Option<u64>,
    /// Active grid vertices stored.
    pub active_vertices: u64,
    /// Active cells stored.
    pub active_cells: u64,
    /// Triangles of the extracted mesh, when extracted.
    pub output_faces: Option<u64>,
    /// Vertices treated as thin shell.
    pub shell_vertices: u64,
    /// Cells touched by the surface.
    pub wall_cells: u64,
}

/// Seconds spent on an item. Run-dependent: excluded from the content digest.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RowTimings {
    /// Loading the file.
    pub load_s: f64,
    /// Converting.
    pub convert_s: f64,
    /// Extracting the mesh.
    pub extract_s: f64,
    /// Encoding the tensors.
    pub encode_s: f64,
    /// The whole item as seen by the supervisor (includes process overhead).
    pub total_s: f64,
    /// Seconds per conversion stage, in order.
    pub stages: Vec<(String, f64)>,
}

/// The encoded tensors of an ok item.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RowTensors {
    /// Active vertex coordinates, `n × 3` `<u2`, sorted lexicographically.
    pub coords: EncodedTensor,
    /// Signed distance per vertex in voxels, `n` `<f4`, negative inside.
    pub sdf: EncodedTensor,
    /// Displacement per vertex in voxels, `n × 3` `<f4`.
    pub deformation: EncodedTensor,
    /// Active cells by minimum corner, `m × 3` `<u2`, sorted.
    pub cells: EncodedTensor,
    /// Extracted mesh vertices in grid coordinates, `v × 3` `<f4`, when stored.
    pub mesh_vertices: Option<EncodedTensor>,
    /// Extracted mesh triangles, `f × 3` `<u4`, when stored.
    pub mesh_faces: Option<EncodedTensor>,
    /// Vector-set samples, when the job draws them.
    pub samples: Option<SampleTensors>,
    /// Appearance per active cell, when the job samples it (`[attributes]`); `None` leaves
    /// the row's journal form and digest as they were before attributes existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub attributes: Option<AttributeTensors>,
    /// The condition views of the item's source, when the job renders them (`[renders]`);
    /// `None` leaves the row's journal form and digest as they were before renders existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub renders: Option<RowRenders>,
}

/// An item's condition views ([`crate::columns::renders`]): a PNG a view, in view order, and
/// the views' `transforms.json`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RowRenders {
    /// The views, in order (`000.png`, `001.png`, …).
    pub views: Vec<RenderedView>,
    /// `transforms.json` of the views (cameras in Blender's Z-up world).
    pub transforms: String,
    /// What of the source's appearance the views could not draw ([`crate::columns::RENDER_NOT_READ`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub not_read: Vec<String>,
}

/// One stored view. The serde form leaves the PNG out (it travels beside the JSON as a
/// blob, as tensor blobs do).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RenderedView {
    /// The view as an 8-bit RGBA PNG file.
    #[serde(skip)]
    pub png: Vec<u8>,
    /// Seconds spent tracing it (run-dependent: not digested).
    pub seconds: f64,
}

/// The encoded appearance of an item's active cells (columns
/// [`crate::columns::ATTRIBUTE_TENSORS`]), one row per row of `cells`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AttributeTensors {
    /// Base colour, `m × 3` `<u1`, sRGB.
    pub base_color: EncodedTensor,
    /// Metallic, `m` `<u1`.
    pub metallic: EncodedTensor,
    /// Roughness, `m` `<u1`.
    pub roughness: EncodedTensor,
    /// Alpha, `m` `<u1`.
    pub alpha: EncodedTensor,
}

impl AttributeTensors {
    /// Encodes sampled attributes.
    pub fn from_attributes(a: &CellAttributes, level: i32) -> Result<Self> {
        Ok(Self {
            base_color: EncodedTensor::from_u8x3(&a.base_color, level)?,
            metallic: EncodedTensor::from_u8(&a.metallic, level)?,
            roughness: EncodedTensor::from_u8(&a.roughness, level)?,
            alpha: EncodedTensor::from_u8(&a.alpha, level)?,
        })
    }

    /// Decodes the attributes (`nearest_cells` is not a tensor and reads 0), checking that
    /// the four have the same number of rows.
    pub fn to_attributes(&self) -> Result<CellAttributes> {
        let a = CellAttributes {
            base_color: self.base_color.to_u8x3(c::BASE_COLOR)?,
            metallic: self.metallic.to_u8(c::METALLIC)?,
            roughness: self.roughness.to_u8(c::ROUGHNESS)?,
            alpha: self.alpha.to_u8(c::ALPHA)?,
            nearest_cells: 0,
        };
        let m = a.base_color.len();
        if [a.metallic.len(), a.roughness.len(), a.alpha.len()] != [m; 3] {
            return Err(SchemaError::Tensor {
                name: "base_color/metallic/roughness/alpha".into(),
                reason: "the four attribute tensors differ in length".into(),
            });
        }
        Ok(a)
    }

    /// The tensors with their column stems, in column order.
    pub fn iter(&self) -> [(&'static str, Option<&EncodedTensor>); 4] {
        [
            (c::BASE_COLOR, Some(&self.base_color)),
            (c::METALLIC, Some(&self.metallic)),
            (c::ROUGHNESS, Some(&self.roughness)),
            (c::ALPHA, Some(&self.alpha)),
        ]
    }

    /// Builds the set from tensors looked up by column stem; `None` when any is missing.
    pub fn from_lookup(
        mut get: impl FnMut(&'static str) -> Result<Option<EncodedTensor>>,
    ) -> Result<Option<Self>> {
        let (Some(base_color), Some(metallic), Some(roughness), Some(alpha)) = (
            get(c::BASE_COLOR)?,
            get(c::METALLIC)?,
            get(c::ROUGHNESS)?,
            get(c::ALPHA)?,
        ) else {
            return Ok(None);
        };
        Ok(Some(Self {
            base_color,
            metallic,
            roughness,
            alpha,
        }))
    }
}

/// What an item's appearance is made of (the row's appearance columns; only with
/// `[attributes]`).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct AppearanceFacts {
    /// Materials the source defines and uses.
    pub materials: u32,
    /// Textures read and used.
    pub textures: u32,
    /// Largest side of those textures, in pixels.
    pub texture_max_size: u32,
    /// Alpha modes of the materials used (glTF names, sorted).
    pub alpha_modes: Vec<String>,
    /// Whether the source has vertex colours.
    pub vertex_colors: bool,
    /// Features not read, each naming where it is.
    pub not_read: Vec<String>,
    /// Active cells that took the closest surface point's values.
    pub nearest_cells: u64,
}

impl AppearanceFacts {
    /// The facts of a read appearance and its sampled cells.
    pub fn new(f: &Facts, a: &CellAttributes) -> Self {
        Self {
            materials: f.materials,
            textures: f.textures,
            texture_max_size: f.largest_texture,
            alpha_modes: f.alpha_modes.clone(),
            vertex_colors: f.vertex_colors,
            not_read: f.not_read.clone(),
            nearest_cells: a.nearest_cells,
        }
    }
}

/// The encoded vector-set samples of an item (columns [`crate::columns::SAMPLE_TENSORS`]):
/// points, normals and distances as `<f2` or `<f4`, occupancy as `<u1`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SampleTensors {
    /// Surface points, `n × 3`.
    pub surface_points: EncodedTensor,
    /// Surface normals, `n × 3`.
    pub surface_normals: EncodedTensor,
    /// Sharp-edge points, `m × 3`.
    pub sharp_points: EncodedTensor,
    /// Sharp-edge normals, `m × 3`.
    pub sharp_normals: EncodedTensor,
    /// Near-surface points, `q × 3`.
    pub near_points: EncodedTensor,
    /// Their signed distances, `q`.
    pub near_sdf: EncodedTensor,
    /// Volume points, `p × 3`.
    pub volume_points: EncodedTensor,
    /// Their signed distances, `p`.
    pub volume_sdf: EncodedTensor,
    /// Their occupancy, `p` bytes.
    pub volume_occupancy: EncodedTensor,
    /// Points near sharp edges and their signed distances, `r × 3` and `r`; `None` when the
    /// job draws none (every job from before the kind existed: its rows, journals and digests
    /// stay as they were).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sharp_near: Option<SharpNearTensors>,
}

/// The encoded sharp-near samples of an item (columns
/// [`crate::columns::OPTIONAL_SAMPLE_TENSORS`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct SharpNearTensors {
    /// Points near sharp edges, `r × 3`.
    pub points: EncodedTensor,
    /// Their signed distances, `r`.
    pub sdf: EncodedTensor,
}

/// Decodes an `[n, 3]` float tensor into points.
fn float_rows(t: &EncodedTensor, name: &str) -> Result<Vec<[f32; 3]>> {
    let v = t.to_floats(name)?;
    if t.shape.len() != 2 || t.shape[1] != 3 {
        return Err(SchemaError::Tensor {
            name: name.into(),
            reason: format!("expected shape [n, 3], found {:?}", t.shape),
        });
    }
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

impl SampleTensors {
    /// Encodes samples drawn with `params` (their values are already rounded to its dtype).
    /// The sharp-near columns are stored when `params` draws sharp-near points (empty for a
    /// mesh without sharp edges), else left out.
    pub fn from_samples(s: &Samples, params: &SampleParams, level: i32) -> Result<Self> {
        let dt = match params.dtype {
            Precision::F16 => DType::F16,
            Precision::F32 => DType::F32,
        };
        let rows = |v: &[[f32; 3]]| {
            EncodedTensor::from_floats(v.as_flattened(), vec![v.len() as u64, 3], dt, level)
        };
        let column = |v: &[f32]| EncodedTensor::from_floats(v, vec![v.len() as u64], dt, level);
        let sharp_near = match params.sharp_near {
            0 => None,
            _ => Some(SharpNearTensors {
                points: rows(&s.sharp_near_points)?,
                sdf: column(&s.sharp_near_sdf)?,
            }),
        };
        Ok(Self {
            surface_points: rows(&s.surface_points)?,
            surface_normals: rows(&s.surface_normals)?,
            sharp_points: rows(&s.sharp_points)?,
            sharp_normals: rows(&s.sharp_normals)?,
            near_points: rows(&s.near_points)?,
            near_sdf: column(&s.near_sdf)?,
            volume_points: rows(&s.volume_points)?,
            volume_sdf: column(&s.volume_sdf)?,
            volume_occupancy: EncodedTensor::from_u8(&s.volume_occupancy, level)?,
            sharp_near,
        })
    }

    /// Decodes the samples (values as `f32`; `sharp_edges` is not stored and reads 0; no
    /// sharp-near columns read as no sharp-near samples).
    pub fn to_samples(&self) -> Result<Samples> {
        let (sharp_near_points, sharp_near_sdf) = match &self.sharp_near {
            Some(t) => (
                float_rows(&t.points, c::SHARP_NEAR_POINTS)?,
                t.sdf.to_floats(c::SHARP_NEAR_SDF)?,
            ),
            None => Default::default(),
        };
        Ok(Samples {
            surface_points: float_rows(&self.surface_points, c::SURFACE_POINTS)?,
            surface_normals: float_rows(&self.surface_normals, c::SURFACE_NORMALS)?,
            sharp_points: float_rows(&self.sharp_points, c::SHARP_POINTS)?,
            sharp_normals: float_rows(&self.sharp_normals, c::SHARP_NORMALS)?,
            near_points: float_rows(&self.near_points, c::NEAR_POINTS)?,
            near_sdf: self.near_sdf.to_floats(c::NEAR_SDF)?,
            sharp_near_points,
            sharp_near_sdf,
            volume_points: float_rows(&self.volume_points, c::VOLUME_POINTS)?,
            volume_sdf: self.volume_sdf.to_floats(c::VOLUME_SDF)?,
            volume_occupancy: self.volume_occupancy.to_u8(c::VOLUME_OCCUPANCY)?,
            sharp_edges: 0,
        })
    }

    /// The tensors with their column stems, in column order (the sharp-near ones `None` when
    /// not stored).
    pub fn iter(&self) -> [(&'static str, Option<&EncodedTensor>); 11] {
        let near = self.sharp_near.as_ref();
        [
            (c::SURFACE_POINTS, Some(&self.surface_points)),
            (c::SURFACE_NORMALS, Some(&self.surface_normals)),
            (c::SHARP_POINTS, Some(&self.sharp_points)),
            (c::SHARP_NORMALS, Some(&self.sharp_normals)),
            (c::NEAR_POINTS, Some(&self.near_points)),
            (c::NEAR_SDF, Some(&self.near_sdf)),
            (c::VOLUME_POINTS, Some(&self.volume_points)),
            (c::VOLUME_SDF, Some(&self.volume_sdf)),
            (c::VOLUME_OCCUPANCY, Some(&self.volume_occupancy)),
            (c::SHARP_NEAR_POINTS, near.map(|t| &t.points)),
            (c::SHARP_NEAR_SDF, near.map(|t| &t.sdf)),
        ]
    }

    /// Mutable access to every present blob, in column order.
    fn blobs_mut(&mut self) -> Vec<&mut Vec<u8>> {
        let mut v = vec![
            &mut self.surface_points.blob,
            &mut self.surface_normals.blob,
            &mut self.sharp_points.blob,
            &mut self.sharp_normals.blob,
            &mut self.near_points.blob,
            &mut self.near_sdf.blob,
            &mut self.volume_points.blob,
            &mut self.volume_sdf.blob,
            &mut self.volume_occupancy.blob,
        ];
        if let Some(t) = self.sharp_near.as_mut() {
            v.extend([&mut t.points.blob, &mut t.sdf.blob]);
        }
        v
    }

    /// Builds the set from tensors looked up by column stem; `None` when any of those every
    /// row with samples has is missing. The sharp-near pair is read when both are present;
    /// one without the other is an error.
    pub fn from_lookup(
        get: impl FnMut(&'static str) -> Result<Option<EncodedTensor>>,
    ) -> Result<Option<Self>> {
        let mut take = get;
        let (Some(a), Some(b), Some(cc), Some(d), Some(e), Some(f), Some(g), Some(h), Some(i)) = (
            take(c::SURFACE_POINTS)?,
            take(c::SURFACE_NORMALS)?,
            take(c::SHARP_POINTS)?,
            take(c::SHARP_NORMALS)?,
            take(c::NEAR_POINTS)?,
            take(c::NEAR_SDF)?,
            take(c::VOLUME_POINTS)?,
            take(c::VOLUME_SDF)?,
            take(c::VOLUME_OCCUPANCY)?,
        ) else {
            return Ok(None);
        };
        let sharp_near = match (take(c::SHARP_NEAR_POINTS)?, take(c::SHARP_NEAR_SDF)?) {
            (Some(points), Some(sdf)) => Some(SharpNearTensors { points, sdf }),
            (None, None) => None,
            _ => {
                return Err(SchemaError::Tensor {
                    name: "sharp_near_points/sharp_near_sdf".into(),
                    reason: "one of the pair is stored without the other".into(),
                })
            }
        };
        Ok(Some(Self {
            surface_points: a,
            surface_normals: b,
            sharp_points: cc,
            sharp_normals: d,
            near_points: e,
            near_sdf: f,
            volume_points: g,
            volume_sdf: h,
            volume_occupancy: i,
            sharp_near,
        }))
    }
}

impl RowTensors {
    /// Encodes the sparse cubes at the given zstd level, the tensors in parallel (each one
    /// frame, so the bytes do not depend on the thread count).
    pub fn from_cubes(cubes: &SparseCubes, level: i32) -> Result<Self> {
        let ((coords, cells), (sdf, deformation)) = rayon::join(
            || {
                rayon::join(
                    || EncodedTensor::from_u16x3(&cubes.coords, level),
                    || EncodedTensor::from_u16x3(&cubes.cells, level),
                )
            },
            || {
                rayon::join(
                    || EncodedTensor::from_f32(&cubes.sdf, level),
                    || EncodedTensor::from_f32x3(&cubes.deformation, level),
                )
            },
        );
        Ok(Self {
            coords: coords?,
            sdf: sdf?,
            deformation: deformation?,
            cells: cells?,
            mesh_vertices: None,
            mesh_faces: None,
            samples: None,
            attributes: None,
            renders: None,
        })
    }

    /// Decodes the sparse cubes, checking that the per-vertex tensors agree in length.
    pub fn to_cubes(&self, resolution: u32, normalization: Normalization) -> Result<SparseCubes> {
        let coords = self.coords.to_u16x3("coords")?;
        let sdf = self.sdf.to_f32("sdf")?;
        let deformation = self.deformation.to_f32x3("deformation")?;
        let cells = self.cells.to_u16x3("cells")?;
        if sdf.len() != coords.len() || deformation.len() != coords.len() {
            return Err(SchemaError::Tensor {
                name: "sdf/deformation".into(),
                reason: format!(
                    "{} coords but {} sdf and {} deformation values",
                    coords.len(),
                    sdf.len(),
                    deformation.len()
                ),
            });
        }
        Ok(SparseCubes {
            resolution,
            normalization,
            coords,
            sdf,
            deformation,
            cells,
        })
    }

    /// Mutable access to every present blob, in column order (for framing blobs apart
    /// from the JSON form).
    pub fn blobs_mut(&mut self) -> Vec<&mut Vec<u8>> {
        let mut v = vec![
            &mut self.coords.blob,
            &mut self.sdf.blob,
            &mut self.deformation.blob,
            &mut self.cells.blob,
        ];
        if let Some(t) = self.mesh_vertices.as_mut() {
            v.push(&mut t.blob);
        }
        if let Some(t) = self.mesh_faces.as_mut() {
            v.push(&mut t.blob);
        }
        if let Some(s) = self.samples.as_mut() {
            v.extend(s.blobs_mut());
        }
        if let Some(a) = self.attributes.as_mut() {
            v.extend([
                &mut a.base_color.blob,
                &mut a.metallic.blob,
                &mut a.roughness.blob,
                &mut a.alpha.blob,
            ]);
        }
        if let Some(r) = self.renders.as_mut() {
            v.extend(r.views.iter_mut().map(|view| &mut view.png));
        }
        v
    }

    /// The tensors in column order with their stems ([`crate::columns::tensors`]).
    pub fn iter(&self) -> Vec<(&'static str, Option<&EncodedTensor>)> {
        let mut v = vec![
            ("coords", Some(&self.coords)),
            ("sdf", Some(&self.sdf)),
            ("deformation", Some(&self.deformation)),
            ("cells", Some(&self.cells)),
            ("mesh_vertices", self.mesh_vertices.as_ref()),
            ("mesh_faces", self.mesh_faces.as_ref()),
        ];
        match &self.samples {
            Some(s) => v.extend(s.iter()),
            None => v.extend(c::SAMPLE_TENSORS.map(|n| (n, None))),
        }
        // Only where present: a row without attributes lists (and digests) as before.
        if let Some(a) = &self.attributes {
            v.extend(a.iter());
        }
        v
    }
}

/// One row of a shard: one manifest item. The serde form leaves tensor blobs out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardRow {
    /// Position in the frozen manifest.
    pub item_index: u64,
    /// Item id.
    pub id: String,
    /// Source path or URI.
    pub uri: String,
    /// sha256 of the source file, when known.
    pub source_sha256: Option<String>,
    /// Outcome.
    pub status: ItemStatus,
    /// Class of the failure (`Some` iff failed).
    pub error_class: Option<ErrorClass>,
    /// Message of the failure.
    pub error_message: Option<String>,
    /// Tail of the item's stderr, when it failed in its process.
    pub stderr_tail: Option<String>,
    /// How many times the item was started.
    pub attempts: u32,
    /// Grid resolution.
    pub resolution: u32,
    /// Normalization, when converted.
    pub normalization: Option<Normalization>,
    /// Counts, when converted.
    pub counts: Option<RowCounts>,
    /// Timings.
    pub timings: RowTimings,
    /// Encoded tensors, when converted.
    pub tensors: Option<RowTensors>,
    /// The item's provenance columns with a value (name → text), from its frozen manifest
    /// line: filled in when the shard is written, stored as `manifest.<name>` columns.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub provenance: BTreeMap<String, String>,
    /// What the item's appearance is made of, when the job samples attributes and the item
    /// converted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub appearance: Option<AppearanceFacts>,
    /// What the conversion measured of the item's source and output, when the job stores the
    /// quality columns and the item converted (`None` leaves the row's journal form and digest
    /// as they were before the columns existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quality: Option<crate::row::quality::QualityFacts>,
    /// The shape signature of the output (`sparcubes::products::shape_signature`), when
    /// converted; `None` in failed rows and in rows of shards written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shape_signature: Option<Vec<f32>>,
}

impl ShardRow {
    /// A failed row for an item.
    pub fn failed(
        item_index: u64,
        id: &str,
        uri: &str,
        resolution: u32,
        class: ErrorClass,
        message: String,
    ) -> Self {
        Self {
            item_index,
            id: id.to_string(),
            uri: uri.to_string(),
            source_sha256: None,
            status: ItemStatus::Failed,
            error_class: Some(class),
            error_message: Some(message),
            stderr_tail: None,
            attempts: 1,
            resolution,
            normalization: None,
            counts: None,
            timings: RowTimings::default(),
            tensors: None,
            provenance: BTreeMap::new(),
            appearance: None,
            quality: None,
            shape_signature: None,
        }
    }

    /// A failed row for a manifest item, carrying the source's sha256 from the manifest
    /// (the one failed row the worker writes, whatever the stage or death).
    pub fn failed_item(
        item: &FrozenItem,
        resolution: u32,
        class: ErrorClass,
        message: String,
    ) -> Self {
        let record = &item.record;
        let mut row = Self::failed(
            item.index,
            &record.id,
            &record.uri,
            resolution,
            class,
            message,
        );
        row.source_sha256 = record.sha256.clone();
        row
    }

    /// Decodes the row's sparse cubes; an error when the row has none.
    pub fn cubes(&self) -> Result<SparseCubes> {
        match (&self.tensors, self.normalization) {
            (Some(t), Some(n)) => t.to_cubes(self.resolution, n),
            _ => Err(SchemaError::Invalid {
                what: "row",
                value: format!("item {} ({}) has no tensors", self.id, self.status.as_str()),
            }),
        }
    }
}
