//! An item's stored condition views (docs/RENDERS.md) as an export writes them: the PNGs as
//! they are, and `transforms.json` with its cameras moved from Blender's Z-up world, where
//! the renderer placed the asset, into the frame of the export's own geometry, so that the
//! views and the voxels of one item agree as they do in the consumer's own data.
//!
//! The stored `transforms.json` says where the asset was put: `blender = scale · zup(source)
//! + offset`, with `zup(x, y, z) = (x, −z, y)` (`sparc3d_render::cond::Placement`). An
//! export's geometry is `export = a · source + b` ([`SourceToExport`]); a camera-to-world
//! matrix `[R | t]` becomes `[zup⁻¹ R | a · zup⁻¹((t − offset) / scale) + b]` (a similarity,
//! so `camera_angle_x` is unchanged), and the file's `scale` and `offset` become `a` and `b`.

use crate::{Error, ExportFile, Placement, Result};
use serde_json::{json, Value};
use sparcubes::Normalization;
use std::path::Path;

/// An item's stored views: a PNG each, in view order, and their `transforms.json`.
#[derive(Debug, Clone, Copy)]
pub struct StoredRenders<'a> {
    /// The PNG files, `000.png` first.
    pub pngs: &'a [&'a [u8]],
    /// `transforms.json` as the job stored it (Blender's Z-up world).
    pub transforms: &'a str,
}

/// Where a source point lands in an export's frame: `a · p + b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourceToExport {
    /// Uniform scale.
    pub a: f64,
    /// Translation, per axis.
    pub b: [f64; 3],
}

impl SourceToExport {
    /// The map of an export that writes a point `p` of the normalized frame (`p = 2 ·
    /// (source − center) · scale`, [`Placement::to_source`]) at `placement.point(p)`.
    pub fn through(placement: &Placement, norm: &Normalization) -> Self {
        let a = placement.factor * 2.0 * norm.scale;
        Self {
            a,
            b: std::array::from_fn(|i| placement.offset[i] - a * norm.center[i]),
        }
    }
}

/// `zup⁻¹`: Blender's Z-up axes back to the source's (`(x, y, z)` → `(x, z, −y)`).
fn from_z_up(v: [f64; 3]) -> [f64; 3] {
    [v[0], v[2], -v[1]]
}

fn number(v: &Value, what: &str) -> Result<f64> {
    v.as_f64()
        .ok_or_else(|| Error::Invalid(format!("transforms.json: {what} is not a number")))
}

fn triple(v: &Value, what: &str) -> Result<[f64; 3]> {
    let a = v
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| Error::Invalid(format!("transforms.json: {what} is not three numbers")))?;
    Ok([
        number(&a[0], what)?,
        number(&a[1], what)?,
        number(&a[2], what)?,
    ])
}

/// The stored `transforms.json` with its cameras in the export's frame (module docs).
pub fn transforms_in(stored: &str, to_export: SourceToExport) -> Result<String> {
    transforms_named(stored, to_export, &three_digits)
}

/// [`transforms_in`] with each frame's `file_path` the view's `name`.
fn transforms_named(
    stored: &str,
    to_export: SourceToExport,
    name: &dyn Fn(usize) -> String,
) -> Result<String> {
    let doc: Value = serde_json::from_str(stored)
        .map_err(|e| Error::Invalid(format!("transforms.json: {e}")))?;
    let scale = number(&doc["scale"], "scale")?;
    let offset = triple(&doc["offset"], "offset")?;
    let frames = doc["frames"]
        .as_array()
        .ok_or_else(|| Error::Invalid("transforms.json: no frames".into()))?;
    let SourceToExport { a, b } = to_export;
    let moved: Vec<Value> = frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let m = &f["transform_matrix"];
            let row = |i: usize| triple(&json!([m[i][0], m[i][1], m[i][2]]), "transform_matrix");
            let column = |r: &[[f64; 3]; 3], j: usize| [r[0][j], r[1][j], r[2][j]];
            let r = [row(0)?, row(1)?, row(2)?];
            let t = [0, 1, 2].map(|i| m[i][3].as_f64().unwrap_or(f64::NAN));
            if t.iter().any(|v| !v.is_finite()) {
                return Err(Error::Invalid(
                    "transforms.json: a camera without a position".into(),
                ));
            }
            // Rows of zup⁻¹ R: zup⁻¹ applied to each column of R.
            let cols = [0, 1, 2].map(|j| from_z_up(column(&r, j)));
            let local = from_z_up([0, 1, 2].map(|i| (t[i] - offset[i]) / scale));
            let p = [0, 1, 2].map(|i| a * local[i] + b[i]);
            let rows: Vec<Value> = (0..3)
                .map(|i| json!([cols[0][i], cols[1][i], cols[2][i], p[i]]))
                .chain([json!([0.0, 0.0, 0.0, 1.0])])
                .collect();
            Ok(json!({
                "file_path": name(i),
                "camera_angle_x": f["camera_angle_x"],
                "transform_matrix": rows,
            }))
        })
        .collect::<Result<_>>()?;
    let out = json!({
        "aabb": [[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]],
        "scale": a,
        "offset": b,
        "frames": moved,
    });
    serde_json::to_string_pretty(&out)
        .map(|s| s + "\n")
        .map_err(|e| Error::Invalid(format!("writing transforms.json: {e}")))
}

/// The name TRELLIS and TRELLIS.2 give view `i`: `000.png`.
pub fn three_digits(i: usize) -> String {
    format!("{i:03}.png")
}

/// The view files of one item under `dir`: each view as stored, named by `name`, and
/// `transforms.json` in the export's frame.
pub fn files(
    renders: &StoredRenders,
    dir: &Path,
    to_export: SourceToExport,
    name: &dyn Fn(usize) -> String,
) -> Result<Vec<ExportFile>> {
    let mut files: Vec<ExportFile> = renders
        .pngs
        .iter()
        .enumerate()
        .map(|(i, png)| ExportFile {
            path: dir.join(name(i)),
            bytes: png.to_vec(),
        })
        .collect();
    files.push(ExportFile {
        path: dir.join("transforms.json"),
        bytes: transforms_named(renders.transforms, to_export, name)?.into_bytes(),
    });
    Ok(files)
}

/// Folder of the plain multi-view layout in an export: `renders/<stem>/`.
pub const PLAIN_DIR: &str = "renders";

/// An item's views in the plain multi-view layout, for consumers whose own data has no
/// condition views: `renders/<stem>/000.png …` and `transforms.json` with the cameras in the
/// frame the export's geometry is written in (`place`, from the normalized frame); nothing
/// when the job rendered none.
pub fn plain(item: &crate::Item, place: &Placement) -> Result<Vec<ExportFile>> {
    let Some(renders) = &item.renders else {
        return Ok(Vec::new());
    };
    let dir = Path::new(PLAIN_DIR).join(item.stem);
    let to_export = SourceToExport::through(place, &item.cubes.normalization);
    files(renders, &dir, to_export, &three_digits)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera at Blender (0, −2, 0.5) looking along +Y, the asset placed by scale 0.5 and
    /// offset (0, 0, −0.25).
    const STORED: &str = r#"{"aabb": [[-0.5,-0.5,-0.5],[0.5,0.5,0.5]], "scale": 0.5, "offset": [0.0, 0.0, -0.25],
      "frames": [{"file_path": "000.png", "camera_angle_x": 0.6,
        "transform_matrix": [[1,0,0,0],[0,0,-1,-2],[0,1,0,0.5],[0,0,0,1]]}]}"#;

    #[test]
    fn a_camera_moves_with_the_asset_into_the_export_frame() {
        // export = 2 · source + (1, 0, 0).
        let to = SourceToExport {
            a: 2.0,
            b: [1.0, 0.0, 0.0],
        };
        let out: Value = serde_json::from_str(&transforms_in(STORED, to).unwrap()).unwrap();
        let m = &out["frames"][0]["transform_matrix"];
        // Blender (0, −2, 0.5) is zup(source) · 0.5 + (0, 0, −0.25): zup(source) = (0, −4, 1.5),
        // source = (0, 1.5, 4), export = (1, 3, 8).
        let position: Vec<f64> = (0..3).map(|i| m[i][3].as_f64().unwrap()).collect();
        assert_eq!(position, vec![1.0, 3.0, 8.0]);
        // Its viewing axis −Z (Blender's +Y, i.e. the source's −Z) stays unit length.
        let forward: Vec<f64> = (0..3).map(|i| -m[i][2].as_f64().unwrap()).collect();
        assert_eq!(forward, vec![0.0, 0.0, -1.0]);
        assert_eq!(out["frames"][0]["camera_angle_x"], 0.6);
        assert_eq!(out["scale"], 2.0);
    }

    #[test]
    fn a_damaged_transforms_file_is_refused_by_what_it_lacks() {
        let to = SourceToExport {
            a: 1.0,
            b: [0.0; 3],
        };
        let e = transforms_in(r#"{"frames": []}"#, to).unwrap_err();
        assert!(e.to_string().contains("scale"), "{e}");
        let e = transforms_in("not json", to).unwrap_err();
        assert!(e.to_string().contains("transforms.json"), "{e}");
    }

    #[test]
    fn through_a_placement_is_the_placement_of_the_normalized_point() {
        let norm = Normalization {
            center: [1.0, -2.0, 0.5],
            scale: 0.25,
        };
        let placement = Placement {
            factor: 0.9,
            offset: [0.1, 0.2, -0.3],
        };
        let to = SourceToExport::through(&placement, &norm);
        let source = [3.0, 1.0, -1.0];
        let normalized: [f32; 3] =
            std::array::from_fn(|i| (2.0 * (source[i] - norm.center[i]) * norm.scale) as f32);
        let expected = placement.point(normalized);
        for i in 0..3 {
            assert!((to.a * source[i] + to.b[i] - expected[i]).abs() < 1e-6);
        }
    }
}
