//! Parts inside closed hulls and closed parts thinner than two voxels (issue 15): enclosed
//! regions decided solid or air by the winding number, sealed vertices decided by it too.
//! The test is on by default (`Params::inside_test`); every conversion here asks for it
//! explicitly, and `off_keeps_the_conversion_without_the_test` checks that off means off and
//! that the default is on.

use sparcubes::mesh::triangle::closest_point_on_triangle;
use sparcubes::{convert, extract, shapes, topology, ConvertStats, Params, SparseCubes, TriMesh};

const N: u32 = 64;

/// The default parameters at resolution `n` with the inside test on.
fn inside_params(n: u32) -> Params {
    Params {
        inside_test: true,
        ..Params::with_resolution(n)
    }
}

fn convert_extract(mesh: &TriMesh, n: u32) -> (SparseCubes, ConvertStats, TriMesh) {
    let conv = convert(mesh, &inside_params(n)).expect("convert");
    let out = extract(&conv.cubes);
    (conv.cubes, conv.stats, out)
}

fn assert_closed_manifold(name: &str, out: &TriMesh) -> u64 {
    let r = topology::check(out);
    assert!(
        r.is_watertight() && r.is_manifold() && r.inconsistently_oriented_edges == 0,
        "{name}: {r:?}"
    );
    r.components
}

/// Distance (voxels) from each output vertex to the nearest of `parts`, with the sources
/// mapped into grid coordinates: per part, (mean, count) over the vertices nearest to it.
fn nearest_part_distances(c: &SparseCubes, parts: &[TriMesh], out: &TriMesh) -> Vec<(f64, u64)> {
    let grid: Vec<Vec<[[f64; 3]; 3]>> = parts
        .iter()
        .map(|m| {
            (0..m.triangles.len())
                .map(|t| {
                    m.triangle(t)
                        .map(|p| c.normalization.source_to_grid(p, c.resolution))
                })
                .collect()
        })
        .collect();
    let mut sums = vec![(0.0, 0u64); parts.len()];
    for p in &out.positions {
        let p = [p[0] as f64, p[1] as f64, p[2] as f64];
        let (part, d) = grid
            .iter()
            .enumerate()
            .map(|(i, tris)| {
                let d = tris
                    .iter()
                    .map(|t| {
                        let q = closest_point_on_triangle(p, t);
                        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2))
                            .sqrt()
                    })
                    .fold(f64::INFINITY, f64::min);
                (i, d)
            })
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
        sums[part].0 += d;
        sums[part].1 += 1;
    }
    sums.into_iter()
        .map(|(s, k)| (if k > 0 { s / k as f64 } else { f64::NAN }, k))
        .collect()
}

/// Voxels per source unit.
fn voxels_per_unit(c: &SparseCubes) -> f64 {
    c.normalization.scale * c.resolution as f64
}

/// A sphere and a cube, the parts the boxes below hold.
fn inner_parts() -> Vec<TriMesh> {
    vec![
        shapes::sphere([-0.45, 0.0, 0.0], 0.35, 24),
        shapes::cuboid([0.15, -0.3, -0.3], [0.75, 0.3, 0.3], &[]),
    ]
}

#[test]
fn parts_inside_a_closed_box_are_kept() {
    // A box with walls 0.1 thick (outer surface out, inner surface in): the space inside is
    // enclosed and air, and holds a closed sphere and a closed cube.
    let mut parts = vec![
        shapes::cuboid([-1.0; 3], [1.0; 3], &[]),
        shapes::flipped(&shapes::cuboid([-0.9; 3], [0.9; 3], &[])),
    ];
    parts.extend(inner_parts());
    let mesh = shapes::merge(&parts);
    let (c, stats, out) = convert_extract(&mesh, N);
    // Outer wall, inner wall (facing into the box), sphere, cube.
    assert_eq!(assert_closed_manifold("closed box", &out), 4);
    assert!(stats.air_regions >= 1, "{stats:?}");
    for (i, (mean, k)) in nearest_part_distances(&c, &parts, &out).iter().enumerate() {
        assert!(*k > 100, "part {i} has {k} output vertices");
        assert!(*mean <= 0.1, "part {i}: mean offset {mean} voxels");
    }
}

#[test]
fn parts_inside_a_box_with_an_open_lid_are_kept() {
    let mut parts = vec![shapes::cuboid([-1.0; 3], [1.0; 3], &[5])];
    parts.extend(inner_parts());
    let mesh = shapes::merge(&parts);
    let (c, _, out) = convert_extract(&mesh, N);
    // The open box becomes one thin shell; the parts stay closed surfaces of their own.
    assert_eq!(assert_closed_manifold("open lid", &out), 3);
    let d = nearest_part_distances(&c, &parts, &out);
    for (i, (mean, k)) in d.iter().enumerate().skip(1) {
        assert!(*k > 100, "part {i} has {k} output vertices");
        assert!(*mean <= 0.1, "part {i}: mean offset {mean} voxels");
    }
}

#[test]
fn a_solid_inside_a_solid_is_one_solid() {
    let outer = shapes::sphere([0.0; 3], 1.0, 32);
    let inner = shapes::sphere([0.0; 3], 0.5, 24);
    let mesh = shapes::merge(&[outer.clone(), inner.clone()]);
    let (c, _, out) = convert_extract(&mesh, N);
    assert_eq!(assert_closed_manifold("nested spheres", &out), 1);
    // No interior surface: every output vertex lies on the outer sphere.
    let d = nearest_part_distances(&c, &[outer, inner], &out);
    assert_eq!(d[1].1, 0, "{} vertices on the inner sphere", d[1].1);
    assert!(d[0].0 <= 0.1, "mean offset {}", d[0].0);
}

#[test]
fn overlapping_parts_keep_the_surfaces_inside_each_other() {
    // A box pushed halfway into another: their overlap (w = 2) is separated from two regions
    // of w = 1 (each box's own inside), so it is not wholly nested and the faces inside the
    // other box stay, as thin sheets inside the solid.
    let a = shapes::cuboid([-0.8, -0.5, -0.5], [0.2, 0.5, 0.5], &[]);
    let b = shapes::cuboid([-0.2, -0.3, -0.3], [0.8, 0.3, 0.3], &[]);
    let (c, stats, out) = convert_extract(&shapes::merge(&[a, b]), N);
    assert_closed_manifold("overlapping boxes", &out);
    assert!(stats.enclosed_regions >= 3, "{stats:?}");
    // The middles of b's face inside a (x = −0.2) and of a's face inside b (x = 0.2).
    for probe in [[-0.2, 0.0, 0.0], [0.2, 0.0, 0.0]] {
        let g = c.normalization.source_to_grid(probe, c.resolution);
        let nearest = out
            .positions
            .iter()
            .map(|p| {
                (0..3)
                    .map(|k| (p[k] as f64 - g[k]).powi(2))
                    .sum::<f64>()
                    .sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 1.0,
            "no output within {nearest} voxels of {probe:?}"
        );
    }
}

#[test]
fn a_box_of_two_sided_faces_stays_a_solid() {
    // Every face twice, once per side, with vertices of their own (as some models do it): the
    // copies cancel, so |w| is 0 inside as outside, but nothing is across the wall. The region
    // is ambiguous and kept solid: the box keeps its exact surface, not a 1.8-voxel shell.
    let one = shapes::cuboid([-0.6; 3], [0.6; 3], &[]);
    let mesh = shapes::merge(&[one.clone(), shapes::flipped(&one)]);
    let (c, stats, out) = convert_extract(&mesh, N);
    assert_eq!(assert_closed_manifold("two-sided box", &out), 1);
    assert_eq!(
        (stats.air_regions, stats.ambiguous_regions),
        (0, 1),
        "{stats:?}"
    );
    let d = nearest_part_distances(&c, &[one], &out);
    assert!(d[0].0 <= 0.1, "mean offset {} voxels", d[0].0);
}

#[test]
fn a_cavity_keeps_its_surface_facing_inward() {
    let cube = shapes::cuboid([-1.0; 3], [1.0; 3], &[]);
    let cavity = shapes::flipped(&shapes::sphere([0.0; 3], 0.5, 24));
    let mesh = shapes::merge(&[cube.clone(), cavity.clone()]);
    let (c, stats, out) = convert_extract(&mesh, N);
    assert_eq!(assert_closed_manifold("cavity", &out), 2);
    assert_eq!(stats.air_regions, 1, "{stats:?}");
    let d = nearest_part_distances(&c, &[cube.clone(), cavity.clone()], &out);
    assert!(d[1].1 > 100 && d[1].0 <= 0.1, "cavity: {:?}", d[1]);
    // The cavity's surface faces inward: it takes its volume off the cube's. (The output is in
    // grid coordinates, the sources in their own.)
    let want = (cube.signed_volume() + cavity.signed_volume()) * voxels_per_unit(&c).powi(3);
    let got = out.signed_volume();
    assert!(
        (got - want).abs() < 0.02 * want,
        "volume {got} voxels, cube minus cavity {want}"
    );
}

/// `m` turned off the grid's axes (about x by 0.5 rad, then about y by 0.3 rad).
fn tilted(mut m: TriMesh) -> TriMesh {
    for (a, b, angle) in [(1usize, 2usize, 0.5f64), (0, 2, 0.3)] {
        let (s, c) = angle.sin_cos();
        for p in &mut m.positions {
            let (y, z) = (p[a] as f64, p[b] as f64);
            p[a] = (c * y - s * z) as f32;
            p[b] = (s * y + c * z) as f32;
        }
    }
    m
}

/// `make(t)` with `t` (source units) chosen so that it is `voxels` voxels at resolution `n`:
/// the voxel is the longest extent over N minus the margins, so solve for t by iteration.
fn in_voxels(voxels: f64, n: u32, make: impl Fn(f64) -> TriMesh) -> TriMesh {
    let margin = 2.0 * Params::with_resolution(n).margin_cells as f64;
    let mut t = voxels * 1.4 / (n as f64 - margin);
    for _ in 0..6 {
        let (lo, hi) = make(t).bounds().expect("bounds");
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        t = voxels * extent / (n as f64 - margin);
    }
    make(t)
}

/// A square plate `thickness` voxels thick at resolution `n`, tilted off the grid's axes.
fn tilted_plate(thickness: f64, n: u32) -> TriMesh {
    in_voxels(thickness, n, |t| {
        tilted(shapes::cuboid(
            [-0.7, -0.7, -t / 2.0],
            [0.7, 0.7, t / 2.0],
            &[],
        ))
    })
}

#[test]
fn thin_closed_plates_keep_their_thickness() {
    for thickness in [0.8, 1.2, 1.6, 2.5] {
        let plate = tilted_plate(thickness, N);
        let (c, stats, out) = convert_extract(&plate, N);
        assert_eq!(assert_closed_manifold("plate", &out), 1);
        let (mean, _) = nearest_part_distances(&c, std::slice::from_ref(&plate), &out)[0];
        // Output thickness: volume over the area of one face (1.4 × 1.4 source units).
        let face = (1.4 * voxels_per_unit(&c)).powi(2);
        let out_thickness = out.signed_volume() / face;
        println!(
            "plate {thickness} voxels: output {out_thickness:.2} voxels thick, mean offset \
             {mean:.3}, thin parts {}, shelled {}",
            stats.thin_parts, stats.shelled_thin_parts
        );
        if thickness >= 1.0 {
            assert!(mean <= 0.25, "plate {thickness}: mean offset {mean} voxels");
            assert!(
                (out_thickness - thickness).abs() <= 0.5,
                "plate {thickness}: output {out_thickness} voxels thick"
            );
        }
    }
}

#[test]
fn parts_overlapping_by_less_than_a_voxel_keep_both_surfaces() {
    // A box pushed 0.9 voxel into a wider one (tilted): their overlap is a slab thinner than
    // a cell inside both (w = 2), whose grid vertices are sealed in. It is no thin part of
    // its own (`regions::OVERLAP_FROM`): inside, both boxes' faces in it would be sheets
    // inside the solid and turn into a cavity 0.9 voxel off each; left outside, it is a thin
    // gap whose walls are the exact faces, the same cubes as without the inside test.
    let mesh = in_voxels(0.9, N, |t| {
        tilted(shapes::merge(&[
            shapes::cuboid([-0.8, -0.8, -0.8], [0.8, 0.8, t / 2.0], &[]),
            shapes::cuboid([-0.5, -0.5, -t / 2.0], [0.5, 0.5, 0.8], &[]),
        ]))
    });
    let (_, stats, out) = convert_extract(&mesh, N);
    assert!(stats.overlap_groups >= 1, "{stats:?}");
    assert_eq!(stats.thin_parts, 0, "{stats:?}");
    assert_closed_manifold("overlapping boxes", &out);
    let without = convert(&mesh, &Params::with_resolution(N)).expect("convert");
    let with = convert(&mesh, &inside_params(N)).expect("convert");
    assert_eq!(with.cubes, without.cubes);
}

#[test]
fn thin_plates_crossing_each_other_keep_their_thickness() {
    // Two 1.2-voxel plates crossing at right angles (tilted): where they cross, the sealed
    // vertices are inside both (w = 2), but joined to the plates' own: that sliver is the
    // plates' inside as the grid sees it, and stays inside (outside it would cut them through
    // and the gap check would shell them).
    let mesh = in_voxels(1.2, N, |t| {
        tilted(shapes::merge(&[
            shapes::cuboid([-0.7, -0.7, -t / 2.0], [0.7, 0.7, t / 2.0], &[]),
            shapes::cuboid([-0.7, -t / 2.0, -0.7], [0.7, t / 2.0, 0.7], &[]),
        ]))
    });
    let (c, stats, out) = convert_extract(&mesh, N);
    println!("crossing plates: {stats:?}");
    assert_eq!(stats.overlap_groups, 0, "{stats:?}");
    assert!(stats.thin_parts >= 1, "{stats:?}");
    assert_closed_manifold("crossing plates", &out);
    let (mean, _) = nearest_part_distances(&c, std::slice::from_ref(&mesh), &out)[0];
    assert!(mean <= 0.25, "mean offset {mean} voxels");
}

#[test]
fn same_cubes_whatever_the_thread_count() {
    let mut parts = vec![
        shapes::cuboid([-1.0; 3], [1.0; 3], &[]),
        shapes::flipped(&shapes::cuboid([-0.9; 3], [0.9; 3], &[])),
        tilted_plate(1.2, N),
    ];
    parts.extend(inner_parts());
    let mesh = shapes::merge(&parts);
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool")
            .install(|| convert(&mesh, &inside_params(N)).expect("convert").cubes)
    };
    assert_eq!(run(1), run(2));
}

#[test]
fn off_keeps_the_conversion_without_the_test() {
    // A sphere in a sphere: with the test (the default) the inner surface goes (one solid);
    // with it off it stays (as a thin sheet inside the solid), and the stats count no region
    // decision.
    let mesh = shapes::merge(&[
        shapes::sphere([0.0; 3], 1.0, 48),
        shapes::sphere([0.0; 3], 0.5, 32),
    ]);
    let off_params = Params {
        inside_test: false,
        ..Params::with_resolution(N)
    };
    let off = convert(&mesh, &off_params).expect("convert");
    let out = extract(&off.cubes);
    let components = assert_closed_manifold("off", &out);
    assert!(
        components >= 2,
        "inner sphere gone without the test: {components}"
    );
    assert_eq!(
        (off.stats.enclosed_regions, off.stats.thin_parts),
        (0, 0),
        "{:?}",
        off.stats
    );
    assert!(!off.stats.stage_seconds.iter().any(|(s, _)| *s == "inside"));
    let (on_cubes, _, on) = convert_extract(&mesh, N);
    assert_eq!(assert_closed_manifold("inside test", &on), 1);
    let default = convert(&mesh, &Params::with_resolution(N)).expect("convert");
    assert_eq!(
        default.cubes, on_cubes,
        "the default is not the inside test"
    );
}

#[test]
fn an_air_pocket_smaller_than_the_grid_can_shape_stays_solid() {
    // A cubic cavity two voxels wide holds one surface-free cell: air by the winding number,
    // but too small to be air (`regions::AIR_MIN_CELLS`), so it stays solid: the same cubes
    // as without the inside test (where the pocket's surface is a sheet inside the solid).
    let margin = 2.0 * Params::with_resolution(N).margin_cells as f64;
    let voxel = 2.0 / (N as f64 - margin);
    let (c, h) = ([0.013, 0.021, 0.007], voxel);
    let cavity = shapes::flipped(&shapes::cuboid(
        [c[0] - h, c[1] - h, c[2] - h],
        [c[0] + h, c[1] + h, c[2] + h],
        &[],
    ));
    let mesh = shapes::merge(&[shapes::cuboid([-1.0; 3], [1.0; 3], &[]), cavity]);
    let (_, stats, out) = convert_extract(&mesh, N);
    assert!(stats.enclosed_regions >= 2, "{stats:?}");
    assert_eq!(stats.air_regions, 0, "{stats:?}");
    assert!(stats.ambiguous_regions >= 1, "{stats:?}");
    assert_closed_manifold("pocket", &out);
    let without = convert(&mesh, &Params::with_resolution(N)).expect("convert");
    let with = convert(&mesh, &inside_params(N)).expect("convert");
    assert_eq!(with.cubes, without.cubes);
}
