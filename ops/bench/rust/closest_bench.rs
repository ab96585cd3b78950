//! Times `closest::TriangleIndex` (build, then a batch of queries near the surface and one in
//! the volume) on a sphere of about a million triangles, the setup of the crate notes on
//! closest-point crates (1M triangles, 1M queries near the surface):
//!
//!     cargo run --release -p sparcubes --example closest_bench [SEGMENTS] [QUERIES]

use sparcubes::queries::closest::TriangleIndex;
use sparcubes::samples::rng::Draw;
use sparcubes::shapes::sphere;
use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let segments: u32 = args.next().and_then(|a| a.parse().ok()).unwrap_or(700);
    let queries: u64 = args
        .next()
        .and_then(|a| a.parse().ok())
        .unwrap_or(1_000_000);
    let mesh = if std::env::var("CUBE").is_ok() {
        // The marching-cubes surface of a cube at the given resolution, in grid units.
        let cube = sparcubes::shapes::cuboid([-1.0; 3], [1.0; 3], &[]);
        let params = sparcubes::Params::with_resolution(segments);
        match sparcubes::convert(&cube, &params) {
            Ok(c) => {
                let mut m = sparcubes::extract(&c.cubes);
                let n = segments as f32;
                for p in &mut m.positions {
                    *p = p.map(|v| 2.0 * v / n - 1.0);
                }
                m
            }
            Err(e) => panic!("{e}"),
        }
    } else {
        sphere([0.0; 3], 1.0, segments)
    };
    let t = Instant::now();
    let index = TriangleIndex::new(&mesh);
    let build = t.elapsed().as_secs_f64();
    let near: Vec<[f64; 3]> = (0..queries)
        .map(|i| {
            let d = Draw::new(1, 1, i);
            let v = [d.normal(0), d.normal(1), d.normal(2)];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let r = 1.0 + 0.01 * d.normal(3);
            v.map(|c| c / l * r)
        })
        .collect();
    let volume: Vec<[f64; 3]> = (0..queries)
        .map(|i| {
            let d = Draw::new(1, 2, i);
            [0, 1, 2].map(|k| 2.1 * d.uniform(k) - 1.05)
        })
        .collect();
    let t = Instant::now();
    let a = index.closest_batch(&near);
    let near_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let b = index.closest_batch(&volume);
    let volume_s = t.elapsed().as_secs_f64();
    let check: f64 = a.iter().chain(&b).map(|c| c.distance).sum();
    println!(
        "{} triangles, {} threads: build {build:.2} s; {queries} near queries {near_s:.2} s; \
         {queries} volume queries {volume_s:.2} s (checksum {check:.3})",
        mesh.triangles.len(),
        rayon::current_num_threads()
    );
}
