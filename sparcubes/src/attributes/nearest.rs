//! Values for the cells no source triangle crosses (a thin shell's far wall, a sealed
//! opening, a filled hole): those at the source surface's closest point to the cell's centre,
//! textures filtered over one cell's area.

use super::shade::{Prepared, Shader, Values};
use super::surface::GridSurface;
use crate::mesh::TriMesh;
use crate::queries::closest::TriangleIndex;
use std::sync::OnceLock;

/// The values a cell takes when the surface has no triangle to be near: all zero.
const FALLBACK: Values = [0.0; 6];

/// The prepared shading of the triangle a lookup was last on (none at first).
#[derive(Default)]
pub struct LastShading<'s>(Option<(u32, Prepared<'s>)>);

/// Closest-point lookups on the source surface, its index built on first use (most meshes'
/// cells are all crossed and never need it).
pub struct Nearest<'s, 'a: 's> {
    surface: &'s GridSurface<'a>,
    shader: &'s Shader<'a>,
    index: OnceLock<Option<TriangleIndex>>,
}

impl<'s, 'a> Nearest<'s, 'a> {
    /// Lookups on `surface`, shaded by `shader`.
    pub fn new(surface: &'s GridSurface<'a>, shader: &'s Shader<'a>) -> Self {
        Self {
            surface,
            shader,
            index: OnceLock::new(),
        }
    }

    /// The index over the surface's triangles (in the order of `surface.triangles`), `None`
    /// when it has none.
    fn index(&self) -> Option<&TriangleIndex> {
        self.index
            .get_or_init(|| {
                let s = self.surface;
                let mesh = TriMesh::new(
                    s.positions.iter().map(|p| p.map(|x| x as f32)).collect(),
                    s.triangles.iter().map(|&(t, _)| s.indices(t)).collect(),
                );
                (!mesh.triangles.is_empty()).then(|| TriangleIndex::new(&mesh))
            })
            .as_ref()
    }

    /// The values at the surface's closest point to each of `cells` (integer minimum
    /// corners), in order. The result does not depend on the thread count.
    pub fn values_at(&self, cells: impl Iterator<Item = [u16; 3]>) -> Vec<Values> {
        let centres: Vec<[f64; 3]> = cells.map(|c| c.map(|x| f64::from(x) + 0.5)).collect();
        let Some(index) = self.index() else {
            return vec![FALLBACK; centres.len()];
        };
        let mut last = LastShading::default();
        index
            .closest_batch(&centres)
            .iter()
            .map(|c| self.values_on(c.triangle, c.point, &mut last))
            .collect()
    }

    /// The values at `point` (grid coordinates) of the surface's triangle `j` (a position in
    /// `surface.triangles`), textures filtered over one cell's area; `last` keeps the
    /// triangle's prepared shading for the next lookup, which is often on the same triangle.
    pub fn values_on(&self, j: u32, point: [f64; 3], last: &mut LastShading<'s>) -> Values {
        let (t, area) = self.surface.triangles[j as usize];
        let shading = match &mut last.0 {
            Some((k, shading)) if *k == j => shading,
            slot => {
                let density = self.shader.uv_density(t, area);
                &slot.insert((j, self.shader.prepare(t, density))).1
            }
        };
        if let Some(v) = shading.constant() {
            return v;
        }
        shading.at(barycentric(point, self.surface.corners(t)), 1.0)
    }

    /// The surface the lookups are on.
    pub fn surface(&self) -> &'s GridSurface<'a> {
        self.surface
    }
}

/// Barycentric coordinates of `p` (on the triangle's plane) in triangle `tri`.
fn barycentric(p: [f64; 3], tri: [[f64; 3]; 3]) -> [f64; 3] {
    use crate::vec3::{dot, sub};
    let (e0, e1, ep) = (sub(tri[1], tri[0]), sub(tri[2], tri[0]), sub(p, tri[0]));
    let (d00, d01, d11) = (dot(e0, e0), dot(e0, e1), dot(e1, e1));
    let (d20, d21) = (dot(ep, e0), dot(ep, e1));
    let den = d00 * d11 - d01 * d01;
    if den.abs() <= 0.0 || !den.is_finite() {
        return [1.0 / 3.0; 3];
    }
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0 - v);
    [1.0 - v - w, v, w]
}
