//! The side of a band vertex ([`Side`]) and its neighbours through grid edges no triangle
//! crosses ([`open_neighbours`]): what the sign stage decides, and what the inside test reads
//! and completes.

use crate::stages::band::Band;
use crate::stages::voxelize::Voxelization;

/// Side of a vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Side {
    /// Not decided yet.
    Unknown = 0,
    /// Outside every closed part.
    Outside = 1,
    /// Inside a closed part.
    Inside = 2,
}

/// The unit steps along x, y and z.
const STEPS: [[i64; 3]; 3] = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

/// Whether the grid edge between `v` and `v + e_axis` is crossed by the surface.
#[inline]
fn blocked(vox: &Voxelization, v: [i64; 3], axis: usize) -> bool {
    vox.blocked[axis].contains(v)
}

/// Neighbours of vertex `c` through grid edges no triangle crosses: (number, coordinate).
pub fn open_neighbours<'a>(
    band: &'a Band,
    vox: &'a Voxelization,
    c: [u32; 3],
) -> impl Iterator<Item = (u32, [u32; 3])> + 'a {
    let v = [c[0] as i64, c[1] as i64, c[2] as i64];
    (0..6).filter_map(move |k| {
        let (axis, dir) = (k / 2, if k % 2 == 0 { -1i64 } else { 1 });
        let step = STEPS[axis];
        let u = [
            v[0] + dir * step[0],
            v[1] + dir * step[1],
            v[2] + dir * step[2],
        ];
        let lower = if dir > 0 { v } else { u };
        if blocked(vox, lower, axis) {
            return None;
        }
        let j = band.verts.id(u)?;
        Some((j, [u[0] as u32, u[1] as u32, u[2] as u32]))
    })
}
