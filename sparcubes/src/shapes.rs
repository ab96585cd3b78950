//! Small generated meshes with known geometry, for tests, examples and benchmarks.

use crate::mesh::TriMesh;
use crate::stages::extract::mc_table::FACE_CORNERS;
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
        close_column(&mut m, &grid, bottom, j, k);
    }
    m
}

/// The triangles of a UV sphere's column between the points `j` and `k` of every row of
/// `grid` (rows from the top down, each around the axis): two between each row and the next,
/// then one down to the pole `bottom`, all outward oriented.
fn close_column(m: &mut TriMesh, grid: &[Vec<u32>], bottom: u32, j: usize, k: usize) {
    for i in 0..grid.len() - 1 {
        let (a, b) = (grid[i][j], grid[i][k]);
        let (cc, d) = (grid[i + 1][j], grid[i + 1][k]);
        m.triangles.push([a, cc, d]);
        m.triangles.push([a, d, b]);
    }
    let last = grid.len() - 1;
    m.triangles.push([bottom, grid[last][k], grid[last][j]]);
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
    // The cube's faces in the one numbering of the crate, counter-clockwise seen from the
    // positive side of their axis: a face on the negative side is turned to face outwards.
    for (f, &c) in FACE_CORNERS.iter().enumerate() {
        if skip.contains(&f) {
            continue;
        }
        let q = if f % 2 == 0 {
            [c[0], c[3], c[2], c[1]]
        } else {
            c
        }
        .map(u32::from);
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

/// A UV sphere of radius `r` around `c` with a round opening at its +z pole, `hole` across
/// (the chord of its rim; `hole` = 2r leaves a hemisphere bowl open at its equator), outward
/// oriented.
pub fn sphere_with_hole(c: [f64; 3], r: f64, hole: f64, segments: u32) -> TriMesh {
    let rim = (0.5 * hole / r).clamp(0.0, 1.0).asin();
    let rings = segments.max(3) as usize;
    let segs = 2 * rings;
    let mut m = TriMesh::default();
    let mut grid = Vec::new();
    for i in 0..rings {
        let th = rim + (PI - rim) * i as f64 / rings as f64;
        let row: Vec<u32> = (0..segs)
            .map(|j| {
                let ph = 2.0 * PI * j as f64 / segs as f64;
                let p = [th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()];
                push(&mut m, std::array::from_fn(|a| c[a] + r * p[a]))
            })
            .collect();
        grid.push(row);
    }
    let bottom = push(&mut m, [c[0], c[1], c[2] - r]);
    for j in 0..segs {
        close_column(&mut m, &grid, bottom, j, (j + 1) % segs);
    }
    m
}

/// A closed surface given by `at(u, v)`, periodic in both parameters over `0..1`, as a grid
/// of quads between the parameter values `us` and `vs` (ascending, starting at 0, each
/// wrapping to the first); the quads for which `skip(i, j)` holds (between `us[i]..us[i+1]`
/// and `vs[j]..vs[j+1]`) are left out. Oriented by the order of `at`'s parameters.
pub fn periodic_surface(
    at: impl Fn(f64, f64) -> [f64; 3],
    us: &[f64],
    vs: &[f64],
    skip: impl Fn(usize, usize) -> bool,
) -> TriMesh {
    let mut m = TriMesh::default();
    for &u in us {
        for &v in vs {
            push(&mut m, at(u, v));
        }
    }
    let (nu, nv) = (us.len(), vs.len());
    for i in 0..nu {
        for j in 0..nv {
            if skip(i, j) {
                continue;
            }
            let id = |i: usize, j: usize| ((i % nu) * nv + j % nv) as u32;
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
    }
    m
}

/// `steps` even parameter values in `0..1` with the values `cut` added (sorted, distinct), and
/// the position of each `cut` value among them.
pub fn parameters(steps: usize, cut: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let mut all: Vec<f64> = (0..steps).map(|i| i as f64 / steps as f64).collect();
    all.extend(cut.iter().map(|c| c.rem_euclid(1.0)));
    all.sort_by(f64::total_cmp);
    all.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    let at = cut
        .iter()
        .map(|c| {
            let c = c.rem_euclid(1.0);
            all.iter().position(|&x| (x - c).abs() < 1e-12).unwrap_or(0)
        })
        .collect();
    (all, at)
}

/// A torus around the z axis through `c` (major radius `big`, minor `small`) with a hole in
/// its outer wall, `hole` across along both directions (none for `hole` = 0), centred on the
/// outer equator at +x. Outward oriented.
pub fn torus_with_hole(c: [f64; 3], big: f64, small: f64, hole: f64, segments: u32) -> TriMesh {
    let du = 0.5 * hole / (2.0 * PI * (big + small));
    let dv = 0.5 * hole / (2.0 * PI * small);
    let at = |u: f64, v: f64| {
        let (u, v) = (2.0 * PI * u, 2.0 * PI * v);
        let rr = big + small * v.cos();
        [
            c[0] + rr * u.cos(),
            c[1] + rr * u.sin(),
            c[2] + small * v.sin(),
        ]
    };
    periodic_with_hole(at, [2 * segments as usize, segments as usize], [du, dv])
}

/// A closed surface `at(u, v)` periodic over `0..1` in both parameters, on `steps` even
/// parameter values each, with a hole around (0, 0) of half-widths `half` (parameter units):
/// the quads between the cuts at −half and +half are left out (none when `half` is 0).
fn periodic_with_hole(
    at: impl Fn(f64, f64) -> [f64; 3],
    steps: [usize; 2],
    half: [f64; 2],
) -> TriMesh {
    let (us, cu) = parameters(steps[0], &[-half[0], half[0]]);
    let (vs, cv) = parameters(steps[1], &[-half[1], half[1]]);
    // The hole's quads: from the cut at −d (which sorts last, near 1) wrapping to +d.
    let inside = |i: usize, lo: usize, hi: usize| {
        if lo > hi {
            i >= lo || i < hi
        } else {
            i >= lo && i < hi
        }
    };
    let holed = half[0] > 0.0 && half[1] > 0.0;
    periodic_surface(at, &us, &vs, |i, j| {
        holed && inside(i, cu[0], cu[1]) && inside(j, cv[0], cv[1])
    })
}

/// A tube of radius `radius` around a trefoil knot (x = sin t + 2 sin 2t, y = cos t − 2 cos 2t,
/// z = −sin 3t, scaled by `scale` around `c`), with a hole `hole` across in its wall at t = 0
/// (none for `hole` = 0). The tube's frame is the knot's Frenet frame, which is periodic (the
/// trefoil's curvature never vanishes), so the tube closes on itself. Outward oriented.
pub fn knot_with_hole(c: [f64; 3], scale: f64, radius: f64, hole: f64, segments: u32) -> TriMesh {
    let curve = |t: f64| {
        [
            t.sin() + 2.0 * (2.0 * t).sin(),
            t.cos() - 2.0 * (2.0 * t).cos(),
            -(3.0 * t).sin(),
        ]
    };
    let d1 = |t: f64| {
        [
            t.cos() + 4.0 * (2.0 * t).cos(),
            -t.sin() + 4.0 * (2.0 * t).sin(),
            -3.0 * (3.0 * t).cos(),
        ]
    };
    let d2 = |t: f64| {
        [
            -t.sin() - 8.0 * (2.0 * t).sin(),
            -t.cos() + 8.0 * (2.0 * t).cos(),
            9.0 * (3.0 * t).sin(),
        ]
    };
    let unit = |a: [f64; 3]| {
        let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        a.map(|x| x / l)
    };
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let speed = {
        let v = d1(0.0);
        scale * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
    };
    let du = 0.5 * hole / (2.0 * PI * speed);
    let dv = 0.5 * hole / (2.0 * PI * radius);
    let at = |u: f64, v: f64| {
        let t = 2.0 * PI * u;
        let tangent = unit(d1(t));
        let binormal = unit(cross(d1(t), d2(t)));
        let normal = cross(binormal, tangent);
        let (cv, sv) = ((2.0 * PI * v).cos(), (2.0 * PI * v).sin());
        let p = curve(t);
        std::array::from_fn(|a| c[a] + scale * p[a] + radius * (cv * normal[a] + sv * binormal[a]))
    };
    periodic_with_hole(at, [16 * segments as usize, segments as usize], [du, dv])
}

/// A cup: an open cylinder around the z axis through `c` from z0 to z1 with a flat bottom at
/// z0, a single sheet open at z1 (its mouth, 2r across).
pub fn cup(c: [f64; 2], r: f64, z0: f64, z1: f64, segments: u32) -> TriMesh {
    let mut m = open_cylinder(c, r, z0, z1, segments);
    let centre = push(&mut m, [c[0], c[1], z0]);
    let s = segments;
    for i in 0..s {
        let j = (i + 1) % s;
        m.triangles.push([centre, 2 * j, 2 * i]);
    }
    m
}

/// A closed block from `lo` to `hi` with a slot cut across its +z face along y: `width`
/// wide (along x, centred) and `depth` deep. The profile in (x, z) is extruded along y.
/// Outward oriented.
pub fn slotted_block(lo: [f64; 3], hi: [f64; 3], width: f64, depth: f64) -> TriMesh {
    let (cx, top) = (0.5 * (lo[0] + hi[0]), hi[2]);
    let (a, b, floor) = (cx - 0.5 * width, cx + 0.5 * width, hi[2] - depth);
    // The profile, counter-clockwise in (x, z) seen from −y.
    let profile = [
        [lo[0], lo[2]],
        [hi[0], lo[2]],
        [hi[0], top],
        [b, top],
        [b, floor],
        [a, floor],
        [a, top],
        [lo[0], top],
    ];
    let mut m = TriMesh::default();
    let front: Vec<u32> = profile
        .iter()
        .map(|p| push(&mut m, [p[0], lo[1], p[1]]))
        .collect();
    let back: Vec<u32> = profile
        .iter()
        .map(|p| push(&mut m, [p[0], hi[1], p[1]]))
        .collect();
    // Sides: one quad per profile edge, facing out of the profile.
    for i in 0..profile.len() {
        let j = (i + 1) % profile.len();
        m.triangles.push([front[i], back[i], back[j]]);
        m.triangles.push([front[i], back[j], front[j]]);
    }
    // Caps: the profile as three fans that share the slot floor's corners.
    let fans: [&[usize]; 3] = [&[0, 1, 4, 5], &[1, 2, 3, 4], &[0, 5, 6, 7]];
    for fan in fans {
        for k in 1..fan.len() - 1 {
            let (p, q, r) = (fan[0], fan[k], fan[k + 1]);
            m.triangles.push([front[p], front[q], front[r]]);
            m.triangles.push([back[p], back[r], back[q]]);
        }
    }
    m
}

/// A closed cylinder around the z axis through `c`: [`open_cylinder`]'s side and two fan
/// caps.
pub fn cylinder(c: [f64; 2], r: f64, z0: f64, z1: f64, segments: u32) -> TriMesh {
    let mut m = open_cylinder(c, r, z0, z1, segments);
    let bottom = push(&mut m, [c[0], c[1], z0]);
    let top = push(&mut m, [c[0], c[1], z1]);
    for i in 0..segments {
        let j = (i + 1) % segments;
        m.triangles.push([bottom, 2 * j, 2 * i]);
        m.triangles.push([top, 2 * i + 1, 2 * j + 1]);
    }
    m
}

/// The mesh moved by a similarity: turned by `angle` about the unit `axis` (Rodrigues'
/// formula), scaled by `scale`, then moved by `offset`.
pub fn similar(
    mesh: &TriMesh,
    axis: [f64; 3],
    angle: f64,
    scale: f64,
    offset: [f64; 3],
) -> TriMesh {
    let (s, c) = angle.sin_cos();
    let k = axis;
    let mut m = mesh.clone();
    for p in &mut m.positions {
        let p64 = p.map(f64::from);
        let dot = k[0] * p64[0] + k[1] * p64[1] + k[2] * p64[2];
        let cross = [
            k[1] * p64[2] - k[2] * p64[1],
            k[2] * p64[0] - k[0] * p64[2],
            k[0] * p64[1] - k[1] * p64[0],
        ];
        *p = [0, 1, 2].map(|a| {
            let turned = p64[a] * c + cross[a] * s + k[a] * dot * (1.0 - c);
            (scale * turned + offset[a]) as f32
        });
    }
    m
}

/// The same surface with every triangle split into three at its centroid.
pub fn split_at_centroids(mesh: &TriMesh) -> TriMesh {
    let mut m = TriMesh::new(mesh.positions.clone(), Vec::new());
    for t in &mesh.triangles {
        let corner = |a: usize| t.map(|i| f64::from(mesh.positions[i as usize][a]));
        let g = push(
            &mut m,
            [0, 1, 2].map(|a| corner(a).iter().sum::<f64>() / 3.0),
        );
        m.triangles
            .extend([[t[0], t[1], g], [t[1], t[2], g], [t[2], t[0], g]]);
    }
    m
}

/// The mesh mirrored in x (its triangles turned back to face out) with every vertex moved
/// by a fixed pseudo-random offset of up to `jitter` times its largest extent along each axis.
pub fn mirrored_jittered(mesh: &TriMesh, jitter: f64) -> TriMesh {
    let extent = mesh.bounds().map_or(0.0, |(lo, hi)| {
        (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max)
    });
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        // Knuth's MMIX linear congruential generator.
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * jitter * extent
    };
    let mut m = mesh.clone();
    for p in &mut m.positions {
        let q = [-f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
        *p = q.map(|x| (x + next()) as f32);
    }
    for t in &mut m.triangles {
        t.swap(1, 2);
    }
    m
}
