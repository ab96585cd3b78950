//! The truncated SDF's band distances two ways on one real mesh: the exact triangle-major scan
//! of every triangle within the truncation (`band::compute_band`, what the sparse-SDF export
//! used first) and the bounded nearest-first queries of `closest::TriangleIndex` that
//! `products::truncated_sdf` uses now. Prints the wall and CPU time of each and how many band
//! points' distances differ by more than 1e-4 voxel:
//!
//!     cargo run --release -p sparcubes --example d3_band_bench -- MESH [RESOLUTION]

use sparcubes::mesh::GridMesh;
use sparcubes::products::truncated_sdf::band_vertices;
use sparcubes::queries::closest::TriangleIndex;
use sparcubes::stages::band::{compute_band, triangle_planes};
use std::path::PathBuf;
use std::process::ExitCode;

/// The band, in voxels: the sparse-SDF export's (`sparc3d-formats`).
const TRUNCATION: f64 = 4.0;

#[path = "common/clock.rs"]
mod clock;
use clock::Clock;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(input) = args.first() else {
        eprintln!("usage: d3_band_bench MESH [RESOLUTION]");
        return ExitCode::FAILURE;
    };
    let resolution = args.get(1).and_then(|r| r.parse().ok()).unwrap_or(512u32);
    let cubes = match sparcubes::io::load(&PathBuf::from(input))
        .map_err(|e| e.to_string())
        .and_then(|l| {
            sparcubes::convert(&l.mesh, &sparcubes::Params::with_resolution(resolution))
                .map_err(|e| e.to_string())
        }) {
        Ok(c) => c.cubes,
        Err(e) => {
            eprintln!("{input}: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mesh = sparcubes::extract(&cubes);
    let verts = band_vertices(&cubes, TRUNCATION);
    // The scan: every grid point of the band (in its brick order) against the triangles of
    // nonzero area within the truncation.
    let grid = GridMesh {
        verts: mesh.positions.iter().map(|p| p.map(f64::from)).collect(),
        tris: (0..mesh.triangles.len())
            .filter(|&t| mesh.face_normal(t) != [0.0; 3])
            .map(|t| mesh.triangles[t])
            .collect(),
    };
    let t = Clock::start();
    let scan = compute_band(&grid, &triangle_planes(&grid), verts.clone(), TRUNCATION);
    let scan_s = t.secs(2);
    // The queries: the same points, bounded by the truncation.
    let t = Clock::start();
    let queries: Vec<[f64; 3]> = scan
        .verts
        .coords()
        .iter()
        .map(|c| c.map(f64::from))
        .collect();
    let tree = TriangleIndex::new(&mesh).closest_batch_within(&queries, TRUNCATION);
    let tree_s = t.secs(2);
    let (mut band, mut differ) = (0usize, 0usize);
    for (s, q) in scan.nearest.iter().zip(&tree) {
        let s = s.udf as f64;
        let q = if q.triangle == u32::MAX {
            TRUNCATION
        } else {
            q.distance
        };
        band += usize::from(s < TRUNCATION || q < TRUNCATION);
        differ += usize::from((s.min(TRUNCATION) - q).abs() > 1e-4);
    }
    println!(
        "{input} at {resolution}: {} triangles, {} grid points, {band} within {TRUNCATION} \
         voxels; scan {scan_s}, tree {tree_s}; {differ} differ by more than 1e-4",
        mesh.triangles.len(),
        queries.len(),
    );
    ExitCode::SUCCESS
}
