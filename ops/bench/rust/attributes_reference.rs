//! Per-cell base colour against an independent reference (issue 43's bar): each mesh is
//! converted at RESOLUTION, its appearance sampled at the active cells as a job with
//! `[attributes]` samples it, and every cell's stored sRGB base colour compared with what a
//! different and simpler method gives it: the source surface's closest point to the cell's
//! centre, its texture coordinates there (the material's set, `KHR_texture_transform` and wrap
//! applied), the nearest texel of the full-size image, times the base colour factor and the
//! vertex colour. The error of a cell is the largest of its three channel differences in sRGB
//! bytes. Prints one JSON line per mesh: its facts, cell counts, the error's median, 90th
//! percentile and mean, and the share of cells over 48/255.
//!
//! A second reference, the `area_*` fields, measures what the sampler is meant to store
//! rather than a point of it: for every cell the source surface crosses, the mean over that
//! surface inside the cell, by brute force: every source triangle cut into a lattice of
//! small triangles (sides at most an eighth of a cell; at most 2048 to a side), each
//! small triangle's centroid coloured by the nearest texel (as above) and weighted by its
//! area, in linear light. No clipping, no mip levels, no code shared with the sampler. Where
//! a texture's detail is finer than a cell, the first reference reads one texel of it and
//! this one their mean:
//!
//!     cargo run --release -p sparcubes --example attributes_reference -- RESOLUTION MESH...
//!
//! `ops/bench/attributes_reference.py` runs it over the textured items of the dev corpus.

use sparcubes::attributes::{sample, CellAttributes};
use sparcubes::colour::{linear_to_srgb, srgb_to_linear};
use sparcubes::io::Buffers;
use sparcubes::materials::{self, Appearance, Image, TextureRef, Wrap};
use sparcubes::queries::closest::{ClosestPoint, TriangleIndex};
use sparcubes::{Params, SparseCubes, TriMesh};
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

#[path = "../../../sparcubes/tests/support/barycentric.rs"]
mod barycentric;
use barycentric::{barycentric_by_areas, doubled_area};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(n) = args.first().and_then(|a| a.parse::<u32>().ok()) else {
        eprintln!("usage: attributes_reference RESOLUTION MESH...");
        return ExitCode::from(2);
    };
    let mut failed = false;
    for path in &args[1..] {
        match measure(Path::new(path), n) {
            Ok(line) => println!("{line}"),
            Err(e) => {
                failed = true;
                println!(
                    "{}",
                    serde_json::json!({"path": path, "error": e.to_string()})
                );
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// Converts and samples `path` at `n`³ and compares every cell with the reference.
fn measure(path: &Path, n: u32) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    let t = Instant::now();
    let loaded = sparcubes::io::load(path)?;
    let cubes = sparcubes::convert(&loaded.mesh, &Params::with_resolution(n))?.cubes;
    let bytes = std::fs::read(path)?;
    let app = materials::read(&bytes, path, Buffers::Folder)?;
    let cells = sample(&cubes, &app);
    let convert_s = t.elapsed().as_secs_f64();
    let found = closest_points(&cubes, &app);
    let mut errors: Vec<u8> = (0..cubes.cells.len())
        .map(|i| {
            let want = found[i].map_or([0; 3], |hit| reference(&cubes, &app, hit));
            error(cells.base_color[i], want)
        })
        .collect();
    let mut area_errors: Vec<u8> = area_means(&cubes, &app)
        .iter()
        .enumerate()
        .filter(|(_, (_, weight))| *weight > 0.0)
        .map(|(i, (sum, weight))| error(cells.base_color[i], srgb(sum.map(|s| s / weight))))
        .collect();
    let mut line = summary(path, n, &app, &cells, &mut errors, convert_s);
    let area = quantiles(&mut area_errors);
    for (key, value) in area {
        line[format!("area_{key}")] = value;
    }
    Ok(line)
}

/// The largest of the three channel differences between `got` and `want`.
fn error(got: [u8; 3], want: [u8; 3]) -> u8 {
    (0..3).map(|c| got[c].abs_diff(want[c])).max().unwrap_or(0)
}

/// Linear RGB as sRGB bytes.
fn srgb(rgb: [f64; 3]) -> [u8; 3] {
    rgb.map(|l| (linear_to_srgb(l as f32) * 255.0).round() as u8)
}

/// For every active cell, the area-weighted sum of the linear base colour over the source
/// surface inside it and that area (zero where no surface is inside), from a lattice of small
/// triangles on every source triangle.
fn area_means(cubes: &SparseCubes, app: &Appearance) -> Vec<([f64; 3], f64)> {
    let mut sums = vec![([0.0; 3], 0.0); cubes.cells.len()];
    for (t, tri) in app.surface.triangles.iter().enumerate() {
        let corners = tri.map(|v| {
            let p = app.surface.positions[v as usize].map(f64::from);
            cubes.normalization.source_to_grid(p, cubes.resolution)
        });
        let side = |a: usize, b: usize| {
            (0..3)
                .map(|k| (corners[a][k] - corners[b][k]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let longest = side(0, 1).max(side(1, 2)).max(side(2, 0));
        if !longest.is_finite() {
            continue;
        }
        let k = ((longest * 8.0).ceil() as usize).clamp(1, 2048);
        let weight = 0.5 * doubled_area(corners[0], corners[1], corners[2]) / (k * k) as f64;
        for (b1, b2) in lattice_centroids(k) {
            let b = [1.0 - b1 - b2, b1, b2];
            let p: [f64; 3] = std::array::from_fn(|a| (0..3).map(|i| b[i] * corners[i][a]).sum());
            let cell = p.map(|x| x.floor().clamp(0.0, f64::from(u16::MAX)) as u16);
            if let Ok(row) = cubes.cells.binary_search(&cell) {
                let rgb = linear_colour(app, t, b);
                let (sum, w) = &mut sums[row];
                for c in 0..3 {
                    sum[c] += weight * rgb[c];
                }
                *w += weight;
            }
        }
    }
    sums
}

/// The barycentric coordinates (of corners 1 and 2) of the centroids of the `k`² equal small
/// triangles that a lattice of `k` steps a side cuts a triangle into.
fn lattice_centroids(k: usize) -> impl Iterator<Item = (f64, f64)> {
    let step = 1.0 / k as f64;
    (0..k).flat_map(move |i| {
        (0..k - i).flat_map(move |j| {
            let up = ((i as f64 + 1.0 / 3.0) * step, (j as f64 + 1.0 / 3.0) * step);
            let down = ((i as f64 + 2.0 / 3.0) * step, (j as f64 + 2.0 / 3.0) * step);
            std::iter::once(up).chain((i + j + 1 < k).then_some(down))
        })
    })
}

/// The closest source point (in the grid frame) to each cell's centre.
fn closest_points(cubes: &SparseCubes, app: &Appearance) -> Vec<Option<ClosestPoint>> {
    let n = cubes.resolution;
    let positions = app
        .surface
        .positions
        .iter()
        .map(|p| {
            let g = cubes.normalization.source_to_grid(p.map(f64::from), n);
            g.map(|x| x as f32)
        })
        .collect();
    let mesh = TriMesh::new(positions, app.surface.triangles.clone());
    let index = TriangleIndex::new(&mesh);
    cubes
        .cells
        .iter()
        .map(|c| index.closest(c.map(|x| x as f64 + 0.5)))
        .collect()
}

/// The reference base colour (sRGB bytes) at the closest point `hit`.
fn reference(cubes: &SparseCubes, app: &Appearance, hit: ClosestPoint) -> [u8; 3] {
    let t = hit.triangle as usize;
    let corners = app.surface.triangles[t].map(|v| {
        let p = app.surface.positions[v as usize].map(f64::from);
        cubes.normalization.source_to_grid(p, cubes.resolution)
    });
    srgb(linear_colour(
        app,
        t,
        barycentric_by_areas(hit.point, corners),
    ))
}

/// The linear base colour on triangle `t` at barycentric `b`: factor × vertex colour ×
/// nearest texel.
fn linear_colour(app: &Appearance, t: usize, b: [f64; 3]) -> [f64; 3] {
    let m = &app.materials[app.surface.material[t] as usize];
    let mut rgb = [0, 1, 2].map(|k| f64::from(m.base_color[k]));
    if let Some(c) = app.surface.color.at(t) {
        for k in 0..3 {
            rgb[k] *= (0..3).map(|i| b[i] * f64::from(c[i][k])).sum::<f64>();
        }
    }
    if let Some(texel) = m.base_color_map.and_then(|tex| texel_at(app, t, tex, b)) {
        for k in 0..3 {
            rgb[k] *= f64::from(srgb_to_linear(f32::from(texel[k]) / 255.0));
        }
    }
    rgb
}

/// The nearest texel of texture `tex` of triangle `t` at barycentric `b`; none when the
/// triangle lacks the coordinate set or the image is missing.
fn texel_at(app: &Appearance, t: usize, tex: TextureRef, b: [f64; 3]) -> Option<[u8; 4]> {
    let image: &Image = app.images.get(tex.image)?.as_ref()?;
    let uv = app.surface.uv[tex.set.min(1)].at(t)?;
    let raw: [f64; 2] = [0, 1].map(|k| (0..3).map(|i| b[i] * f64::from(uv[i][k])).sum());
    let m = tex.transform;
    let at = [0, 1]
        .map(|k| f64::from(m[k][0]) * raw[0] + f64::from(m[k][1]) * raw[1] + f64::from(m[k][2]));
    let x = wrapped(at[0], tex.wrap[0], image.width);
    let y = wrapped(at[1], tex.wrap[1], image.height);
    image.pixels.get(y * image.width as usize + x).copied()
}

/// The texel index along one axis of `size` texels for coordinate `c` under `wrap`.
fn wrapped(c: f64, wrap: Wrap, size: u32) -> usize {
    let f = match wrap {
        Wrap::Repeat => c.rem_euclid(1.0),
        Wrap::Clamp => c.clamp(0.0, 1.0),
        Wrap::Mirror => {
            let m = c.rem_euclid(2.0);
            if m > 1.0 {
                2.0 - m
            } else {
                m
            }
        }
    };
    ((f * f64::from(size)) as usize).min(size as usize - 1)
}

/// The JSON line of one mesh.
fn summary(
    path: &Path,
    n: u32,
    app: &Appearance,
    cells: &CellAttributes,
    errors: &mut [u8],
    convert_s: f64,
) -> serde_json::Value {
    let f = &app.facts;
    let mut line = serde_json::json!({
        "path": path.display().to_string(),
        "resolution": n,
        "materials": f.materials,
        "textures": f.textures,
        "largest_texture": f.largest_texture,
        "vertex_colors": f.vertex_colors,
        "alpha_modes": f.alpha_modes,
        "not_read": f.not_read,
        "nearest_cells": cells.nearest_cells,
        "seconds": convert_s,
    });
    for (key, value) in quantiles(errors) {
        line[key] = value;
    }
    line
}

/// The errors' count (`cells`), median, 90th percentile, mean and share over 48.
fn quantiles(errors: &mut [u8]) -> [(&'static str, serde_json::Value); 5] {
    errors.sort_unstable();
    let k = errors.len().max(1);
    let at = |q: usize| errors.get((errors.len() * q / 100).min(k - 1)).copied();
    let mean = errors.iter().map(|&e| f64::from(e)).sum::<f64>() / k as f64;
    let over = errors.iter().filter(|&&e| e > 48).count() as f64 / k as f64;
    [
        ("cells", errors.len().into()),
        ("median", at(50).into()),
        ("p90", at(90).into()),
        ("mean", mean.into()),
        ("over_48", over.into()),
    ]
}
