//! One asset's condition views as they are stored and written: a PNG per view, the seconds
//! each took, `transforms.json`, and which views see nothing. `sparc3d render` and a job's
//! workers (`[renders]`) both go through [`render_asset`], so the same source and seed give
//! the same bytes from either.

use super::passes::{self, Pass};
use super::{render_views, transforms_json, Placement, Request, Surface};
use sparcubes::materials::Appearance;
use sparcubes::TriMesh;

/// An asset's rendered views, encoded.
#[derive(Debug, Clone, PartialEq)]
pub struct AssetViews {
    /// Each view as an 8-bit RGBA PNG, in view order (`000.png`, `001.png`, …).
    pub pngs: Vec<Vec<u8>>,
    /// Each view's passes asked for (`Request::passes`), as PNGs, in [`Pass::ALL`]'s order.
    pub passes: Vec<Vec<(Pass, Vec<u8>)>>,
    /// Seconds spent tracing each view (reading and encoding excluded).
    pub seconds: Vec<f64>,
    /// `transforms.json` ([`transforms_json`]), in Blender's Z-up world.
    pub transforms: String,
    /// Side of every view in pixels.
    pub size: u32,
    /// Views whose alpha is zero everywhere (0-based).
    pub empty: Vec<usize>,
}

impl AssetViews {
    /// Why these views cannot stand for the asset, if they cannot: a view that sees nothing
    /// of it (a condition image the loaders would crop to nothing).
    pub fn problem(&self) -> Option<String> {
        let first = *self.empty.first()?;
        Some(format!(
            "{} of {} views see nothing of the asset (view {first:03} first)",
            self.empty.len(),
            self.pngs.len()
        ))
    }
}

/// Seed of an asset from the first 8 bytes of its source's sha256, mixed with `extra`
/// (`--seed`, `[renders] seed`): every random draw of its views comes from it.
pub fn seed_of(sha256_head: [u8; 8], extra: u64) -> u64 {
    u64::from_le_bytes(sha256_head) ^ extra.wrapping_mul(0x9E37_79B9_7F4A_7C15)
}

/// `appearance` when it has colours worth drawing (materials, textures or vertex colours);
/// a surface without them is drawn in the plain grey.
pub fn with_colours(appearance: Appearance) -> Option<Appearance> {
    let f = &appearance.facts;
    (f.materials > 0 || f.textures > 0 || f.vertex_colors).then_some(appearance)
}

/// Renders and encodes the views `request` asks for of `mesh` (placed by its bounding box,
/// [`Placement::of`]), in `appearance`'s colours when given. An error when the mesh has no
/// triangles or a view cannot be encoded; views that see nothing are listed in
/// [`AssetViews::empty`], for the caller to refuse.
pub fn render_asset(
    mesh: &TriMesh,
    appearance: Option<&Appearance>,
    request: &Request,
) -> Result<AssetViews, String> {
    if mesh.triangles.is_empty() {
        return Err("the mesh has no triangles: nothing to render".into());
    }
    let placement = Placement::of(&mesh.positions);
    let surface = Surface::new(mesh, appearance, &placement);
    let views = render_views(&surface, request);
    let pngs = views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v.image
                .encode_png()
                .map_err(|e| format!("encoding view {i:03} as PNG: {e}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let passes = views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            request
                .passes
                .iter()
                .map(|p| {
                    Ok((
                        p,
                        passes::encode(p, v).map_err(|e| format!("view {i:03}: {e}"))?,
                    ))
                })
                .collect::<Result<Vec<_>, String>>()
        })
        .collect::<Result<Vec<_>, _>>()?;
    let empty = views
        .iter()
        .enumerate()
        .filter(|(_, v)| v.image.rgba.chunks(4).all(|p| p[3] == 0))
        .map(|(i, _)| i)
        .collect();
    Ok(AssetViews {
        pngs,
        passes,
        seconds: views.iter().map(|v| v.seconds).collect(),
        transforms: transforms_json(&placement, &views),
        size: views.first().map_or(0, |v| v.image.size),
        empty,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cond::Recipe;

    fn request(seed: u64) -> Request {
        Request {
            recipe: Recipe::Trellis2,
            views: Some(3),
            size: Some(48),
            seed,
            passes: Default::default(),
        }
    }

    #[test]
    fn the_same_mesh_and_seed_give_the_same_bytes_and_another_seed_other_views() {
        let mesh = sparcubes::shapes::sphere([0.0; 3], 0.4, 12);
        let a = render_asset(&mesh, None, &request(7)).unwrap();
        let b = render_asset(&mesh, None, &request(7)).unwrap();
        assert_eq!(
            a,
            AssetViews {
                seconds: a.seconds.clone(),
                ..b
            }
        );
        assert_eq!(a.pngs.len(), 3);
        assert!(a.empty.is_empty() && a.problem().is_none());
        let c = render_asset(&mesh, None, &request(8)).unwrap();
        assert_ne!(a.transforms, c.transforms);
        assert!(a.pngs.iter().all(|p| p.starts_with(b"\x89PNG")));
    }

    #[test]
    fn a_mesh_without_triangles_is_refused_by_name() {
        let mesh = TriMesh {
            positions: vec![[0.0; 3]],
            triangles: vec![],
        };
        let e = render_asset(&mesh, None, &request(1)).unwrap_err();
        assert!(e.contains("no triangles"), "{e}");
    }

    #[test]
    fn views_that_see_nothing_are_a_problem_named_by_count_and_first_view() {
        let mesh = sparcubes::shapes::sphere([0.0; 3], 0.4, 8);
        let mut views = render_asset(&mesh, None, &request(3)).unwrap();
        views.empty = vec![1, 2];
        let problem = views.problem().unwrap_or_default();
        assert_eq!(
            problem,
            "2 of 3 views see nothing of the asset (view 001 first)"
        );
    }

    #[test]
    fn the_seed_is_the_sha256_head_mixed_with_the_extra_seed() {
        let head = [1, 2, 3, 4, 5, 6, 7, 8];
        assert_eq!(seed_of(head, 0), u64::from_le_bytes(head));
        assert_ne!(seed_of(head, 1), seed_of(head, 0));
    }
}
