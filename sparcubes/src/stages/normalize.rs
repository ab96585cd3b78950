//! Stage 1: the mesh fitted into the grid with a margin ([`crate::grid::normalization`]), in
//! grid coordinates and double precision, without its zero-area triangles.

use crate::error::{Error, Result};
use crate::grid::normalization::Normalization;
use crate::mesh::{GridMesh, TriMesh};
use crate::params::Params;
use crate::vec3::{cross, sub};

/// The mesh in grid coordinates without zero-area triangles, the normalization that put it
/// there (`fit`, else the source's box fitted to `params.span()`), and how many triangles had
/// zero area. A mesh must be sanitised ([`checked_bounds`]); one whose every triangle has
/// zero area is refused.
pub fn normalize(
    mesh: &TriMesh,
    params: &Params,
    fit: Option<Normalization>,
) -> Result<(GridMesh, Normalization, u64)> {
    let n = params.resolution;
    let bounds = checked_bounds(mesh)?;
    let norm = fit.unwrap_or_else(|| Normalization::fit_span(bounds, n, params.span()));
    let (grid, degenerate) = to_grid(mesh, &norm, n);
    if grid.tris.is_empty() {
        return Err(Error::EmptyMesh {
            context: "convert".into(),
            reason: format!("all {degenerate} triangles have zero area"),
        });
    }
    Ok((grid, norm, degenerate))
}

/// Checks that a mesh is sanitised (indices in range, finite coordinates, an extent the grid
/// can hold) and returns its bounds.
fn checked_bounds(mesh: &TriMesh) -> Result<([f64; 3], [f64; 3])> {
    if let Some(bad) = mesh
        .triangles
        .iter()
        .flatten()
        .find(|&&i| i as usize >= mesh.positions.len())
    {
        return Err(Error::InvalidParams(format!(
            "mesh has index {bad} but only {} vertices (sanitise it first)",
            mesh.positions.len()
        )));
    }
    if mesh.positions.iter().flatten().any(|c| !c.is_finite()) {
        return Err(Error::InvalidParams(
            "mesh has non-finite coordinates (sanitise it first)".into(),
        ));
    }
    let bounds = mesh.bounds().ok_or_else(|| Error::EmptyMesh {
        context: "convert".into(),
        reason: "no triangles".into(),
    })?;
    crate::grid::normalization::check_extent(bounds, "convert")?;
    Ok(bounds)
}

/// The mesh in grid coordinates, without zero-area triangles.
fn to_grid(mesh: &TriMesh, norm: &Normalization, n: u32) -> (GridMesh, u64) {
    let verts: Vec<[f64; 3]> = mesh
        .positions
        .iter()
        .map(|p| norm.source_to_grid([p[0] as f64, p[1] as f64, p[2] as f64], n))
        .collect();
    let mut grid = GridMesh {
        verts,
        tris: Vec::with_capacity(mesh.triangles.len()),
    };
    let mut degenerate = 0;
    for &t in &mesh.triangles {
        grid.tris.push(t);
        let [a, b, c] = grid.tri(grid.tris.len() - 1);
        if cross(sub(b, a), sub(c, a)) == [0.0; 3] {
            grid.tris.pop();
            degenerate += 1;
        }
    }
    (grid, degenerate)
}
