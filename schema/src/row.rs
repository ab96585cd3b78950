//! One shard row in memory: an item's outcome, counts, timings and encoded tensors.

use crate::class::{ErrorClass, ItemStatus};
use crate::error::{Result, SchemaError};
use crate::manifest::FrozenItem;
use crate::tensor::EncodedTensor;
use serde::{Deserialize, Serialize};
use sparcubes::{Normalization, SparseCubes};

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
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
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
        v
    }

    /// The tensors in column order with their stems ([`crate::columns::TENSORS`]).
    pub fn iter(&self) -> [(&'static str, Option<&EncodedTensor>); 6] {
        [
            ("coords", Some(&self.coords)),
            ("sdf", Some(&self.sdf)),
            ("deformation", Some(&self.deformation)),
            ("cells", Some(&self.cells)),
            ("mesh_vertices", self.mesh_vertices.as_ref()),
            ("mesh_faces", self.mesh_faces.as_ref()),
        ]
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
