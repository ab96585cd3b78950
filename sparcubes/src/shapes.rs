//! Small generated meshes with known geometry, for tests, examples and benchmarks.

use crate::mesh::TriMesh;
use std::f64::consts::PI;

fn push(m: &mut TriMesh, p: [f64; 3]) -> u32 {
    m.positions.push([p[0] as f32, p[1] as f32, p[2] as f32]);
    (m.positions.len() - 1) as u32
}

/// A UV sphere of radius `r` around `c`, outward oriented, closed.
pub fn sphere(c: [f64; 3], r: f64, segments: u32) -> TriMesh {
    let rings = segments.max(3);
    let segs = 2 * rings;
    let mut m = TriMesh::default();
    let top = push(&mut m, [c[0], c[1], c[2] + r]);
    let mut grid = Vec::new();
    for i in 1..rings {
        let th = PI * i as f64 / rings as f64;
        let row: Vec<u32> = (0..segs)
            .map(|j| {
                let ph = 2.0 * PI * j as f64 / segs as f64;
                push(
                    &mut m,
                    [
                        c[0] + r * th.sin() * ph.cos(),
                        c[1] + r * th.sin() * ph.sin(),
                        c[2] + r * th.cos(),
                    ],
                )
            })
            .collect();
        grid.push(row);
    }
    let bottom = push(&mut m, [c[0], c[1], c[2] - r]);
    let s = segs as usize;
    for j in 0..s {
        let k = (j + 1) % s;
        m.triangles.push([top, grid[0][j], grid[0][k]]);
        for i in 0..grid.len() - 1 {
            let (a, b) = (grid[i][j], grid[i][k]);
            let (cc, d) = (grid[i + 1][j], grid[i + 1][k]);
            m.triangles.push([a, cc, d]);
            m.triangles.push([a, d, b]);
        }
        let last = grid.len() - 1;
        m.triangles.push([bottom, grid[last][k], grid[last][j]]);
    }
    m
}

/// An axis-aligned box from `lo` to `hi`, outward oriented; `skip` removes the faces whose
/// index is listed (0: −x, 1: +x, 2: −y, 3: +y, 4: −z, 5: +z).
pub fn cuboid(lo: [f64; 3], hi: [f64; 3], skip: &[usize]) -> TriMesh {
    let mut m = TriMesh::default();
    let corner = |i: usize| {
        [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ]
    };
    for i in 0..8 {
        push(&mut m, corner(i));
    }
    // Quads as corner indices, counter-clockwise seen from outside.
    let faces = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    for (f, q) in faces.iter().enumerate() {
        if skip.contains(&f) {
            continue;
        }
        m.triangles.push([q[0], q[1], q[2]]);
        m.triangles.push([q[0], q[2], q[3]]);
    }
    m
}

/// A cube from `lo` to `hi` whose +z face has a square hole of side `hole` at its centre
/// (the face is split into four quads around the hole).
pub fn cube_with_hole(lo: [f64; 3], hi: [f64; 3], hole: f64) -> TriMesh {
    let mut m = cuboid(lo, hi, &[5]);
    let (cx, cy, z) = (0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), hi[2]);
    let h = 0.5 * hole;
    let xs = [lo[0], cx - h, cx + h, hi[0]];
    let ys = [lo[1], cy - h, cy + h, hi[1]];
    let mut ids = [[0u32; 4]; 4];
    for (i, &x) in xs.iter().enumerate() {
        for (j, &y) in ys.iter().enumerate() {
            ids[i][j] = push(&mut m, [x, y, z]);
        }
    }
    for i in 0..3 {
        for j in 0..3 {
            if i == 1 && j == 1 {
                continue;
            }
            let (a, b, c, d) = (ids[i][j], ids[i + 1][j], ids[i + 1][j + 1], ids[i][j + 1]);
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    m
}

/// A torus around the z axis through `c`, major radius `big`, minor radius `small`.
pub fn torus(c: [f64; 3], big: f64, small: f64, segments: u32) -> TriMesh {
    let (nu, nv) = (2 * segments as usize, segments as usize);
    let mut m = TriMesh::default();
    for i in 0..nu {
        let u = 2.0 * PI * i as f64 / nu as f64;
        for j in 0..nv {
            let v = 2.0 * PI * j as f64 / nv as f64;
            let rr = big + small * v.cos();
            push(
                &mut m,
                [
                    c[0] + rr * u.cos(),
                    c[1] + rr * u.sin(),
                    c[2] + small * v.sin(),
                ],
            );
        }
    }
    for i in 0..nu {
        for j in 0..nv {
            let a = (i * nv + j) as u32;
            let b = (((i + 1) % nu) * nv + j) as u32;
            let c2 = (((i + 1) % nu) * nv + (j + 1) % nv) as u32;
            let d = (i * nv + (j + 1) % nv) as u32;
            m.triangles.push([a, b, c2]);
            m.triangles.push([a, c2, d]);
        }
    }
    m
}

/// A single quad (two triangles) in the plane z = `z`, from (x0, y0) to (x1, y1): an open
/// sheet.
pub fn quad(x0: f64, y0: f64, x1: f64, y1: f64, z: f64) -> TriMesh {
    let mut m = TriMesh::default();
    let a = push(&mut m, [x0, y0, z]);
    let b = push(&mut m, [x1, y0, z]);
    let c = push(&mut m, [x1, y1, z]);
    let d = push(&mut m, [x0, y1, z]);
    m.triangles = vec![[a, b, c], [a, c, d]];
    m
}

/// An open cylinder (no caps) around the z axis through `c`, from z0 to z1.
pub fn open_cylinder(c: [f64; 2], r: f64, z0: f64, z1: f64, segments: u32) -> TriMesh {
    let mut m = TriMesh::default();
    let s = segments as usize;
    for i in 0..s {
        let a = 2.0 * PI * i as f64 / s as f64;
        push(&mut m, [c[0] + r * a.cos(), c[1] + r * a.sin(), z0]);
        push(&mut m, [c[0] + r * a.cos(), c[1] + r * a.sin(), z1]);
    }
    for i in 0..s {
        let j = (i + 1) % s;
        let (a, b, cc, d) = (
            2 * i as u32,
            2 * j as u32,
            2 * j as u32 + 1,
            2 * i as u32 + 1,
        );
        m.triangles.push([a, b, cc]);
        m.triangles.push([a, cc, d]);
    }
    m
}

/// Concatenates meshes into one (disjoint parts).
pub fn merge(parts: &[TriMesh]) -> TriMesh {
    let mut m = TriMesh::default();
    for p in parts {
        let base = m.positions.len() as u32;
        m.positions.extend_from_slice(&p.positions);
        m.triangles.extend(
            p.triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }
    m
}

/// The same mesh with every triangle's orientation reversed.
pub fn flipped(mesh: &TriMesh) -> TriMesh {
    let mut m = mesh.clone();
    for t in &mut m.triangles {
        t.swap(1, 2);
    }
    m
}
