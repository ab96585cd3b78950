//! Condition renders: the views an image-to-3D trainer conditions on, rendered on the CPU by
//! ray casting (obvhs, through `sparc3d-raycast`) with each consumer's cameras and an
//! approximation of its lights, in the layout its loader reads (docs/RENDERS.md).
//!
//! The asset is placed as the peers' Blender scripts place it (`normalize_scene` in
//! TRELLIS's `dataset_toolkits/blender_script/render.py` and TRELLIS.2's
//! `data_toolkit/blender_script/render_cond.py`): imported Y-up into Blender's Z-up world
//! (`(x, y, z)` → `(x, −z, y)`, as Blender's glTF and OBJ importers turn it), scaled so that
//! its bounding box's longest side is 1 and moved so that the box is centred on the origin;
//! `transforms.json` records that `scale` and `offset` with each view's `camera_angle_x` and
//! camera-to-world `transform_matrix` ([`cameras`]). Views are traced by [`picture`], lit by
//! [`lights`], every random draw from a generator seeded per item ([`rng`]): the same source
//! and seed give the same bytes, whatever the thread count.

pub mod asset;
pub mod cameras;
pub mod lights;
pub mod passes;
pub mod picture;
pub mod rng;
pub mod thumbnail;

use cameras::{PerspectiveCamera, View};
use glam::{DVec3, Vec3A};
use lights::Lights;
use passes::{Pass, PassSet};
use picture::{PassData, RgbaImage};
use rng::SplitMix64;
use sparc3d_raycast::Scene;
use sparcubes::attributes::shade::Shader;
use sparcubes::materials::Appearance;
use sparcubes::TriMesh;

/// Whose condition views to render: their cameras, count, size and lights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Recipe {
    /// TRELLIS (`dataset_toolkits/render_cond.py`): 24 views at 1024², three fixed lights.
    Trellis,
    /// TRELLIS.2 (`data_toolkit/render_cond.py`): 16 views at 1024², a white world and 1–3
    /// random point lights per view.
    Trellis2,
}

impl Recipe {
    /// Every recipe, by name.
    pub const ALL: [(&'static str, Recipe); 2] =
        [("trellis", Recipe::Trellis), ("trellis2", Recipe::Trellis2)];

    /// The recipe named `name` (`trellis`, `trellis2`).
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, r)| *r)
    }

    /// The recipe's name, as [`Recipe::named`] reads it.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, r)| *r == self)
            .map_or("trellis2", |(n, _)| n)
    }

    /// Views per asset in the consumer's own script.
    pub fn views(self) -> u32 {
        match self {
            Recipe::Trellis => 24,
            Recipe::Trellis2 => 16,
        }
    }

    /// Side of a view in pixels in the consumer's own script.
    pub fn size(self) -> u32 {
        1024
    }
}

/// Where the asset was put: `blender = scale · zup(source) + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// The scale applied after the axis turn (1 / the longest side of the bounding box).
    pub scale: f64,
    /// The translation applied after scaling (minus the scaled box's centre).
    pub offset: [f64; 3],
}

/// A source point turned from Y-up into Blender's Z-up.
fn z_up(p: [f32; 3]) -> DVec3 {
    DVec3::new(p[0] as f64, -(p[2] as f64), p[1] as f64)
}

impl Placement {
    /// The placement of a mesh with `positions` (a unit scale at the origin for none).
    pub fn of(positions: &[[f32; 3]]) -> Self {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for &p in positions {
            let q = z_up(p);
            if q.is_finite() {
                lo = lo.min(q);
                hi = hi.max(q);
            }
        }
        let longest = (hi - lo).max_element();
        if !(longest.is_finite() && longest > 0.0) {
            return Self {
                scale: 1.0,
                offset: [0.0; 3],
            };
        }
        let scale = 1.0 / longest;
        Self {
            scale,
            offset: (-(lo + hi) * 0.5 * scale).to_array(),
        }
    }

    /// `p` of the source in Blender's normalized frame.
    pub fn place(&self, p: [f32; 3]) -> DVec3 {
        z_up(p) * self.scale + DVec3::from(self.offset)
    }
}

/// The asset ready to trace: its surface placed, its BVH, and its appearance when read.
pub struct Surface<'a> {
    scene: Scene,
    corners: Vec<[Vec3A; 3]>,
    /// Source units to placed units.
    scale: f64,
    /// The appearance's shader and its triangles' areas (source units²), when read.
    shaded: Option<(Shader<'a>, Vec<f64>)>,
}

/// The base colour of a surface without an appearance (linear mid grey).
const PLAIN: [f32; 4] = [0.5, 0.5, 0.5, 1.0];

impl<'a> Surface<'a> {
    /// `mesh` placed by `placement`, in `appearance`'s colours when given (then its surface
    /// is the one traced, so that triangle numbers agree with its materials).
    pub fn new(mesh: &TriMesh, appearance: Option<&'a Appearance>, placement: &Placement) -> Self {
        let (positions, triangles) = match appearance {
            Some(a) => (&a.surface.positions, &a.surface.triangles),
            None => (&mesh.positions, &mesh.triangles),
        };
        let placed: Vec<[f32; 3]> = positions
            .iter()
            .map(|&p| placement.place(p).as_vec3().to_array())
            .collect();
        let corners = triangles
            .iter()
            .map(|t| {
                t.map(|i| {
                    placed
                        .get(i as usize)
                        .map_or(Vec3A::ZERO, |&c| Vec3A::from(c))
                })
            })
            .collect();
        let shaded = appearance.map(|a| (Shader::new(a), crate::paint::triangle_areas(a)));
        Self {
            scene: Scene::new(&placed, triangles),
            corners,
            scale: placement.scale,
            shaded,
        }
    }

    /// Linear RGBA of triangle `t` at `point` (placed), textures filtered over a pixel of
    /// side `footprint` (source units).
    fn albedo(&self, t: usize, point: Vec3A, footprint: f64) -> [f32; 4] {
        let Some((shader, areas)) = &self.shaded else {
            return PLAIN;
        };
        let Some(&area) = areas.get(t) else {
            return PLAIN;
        };
        let bary = barycentric(point, self.corners[t]);
        let v = shader.at(t, bary, footprint * footprint, shader.uv_density(t, area));
        [v[0], v[1], v[2], v[5]]
    }
}

/// Barycentric coordinates of `p` in triangle `t` (the preview's, clamped), as doubles.
fn barycentric(p: Vec3A, t: [Vec3A; 3]) -> [f64; 3] {
    crate::barycentric(p, t).map(f64::from)
}

/// One rendered view: its camera as the consumer describes it, and its picture.
pub struct RenderedView {
    /// Yaw, pitch, distance and FoV.
    pub view: View,
    /// The camera those give.
    pub camera: PerspectiveCamera,
    /// The RGBA picture.
    pub image: RgbaImage,
    /// What the passes asked for need of its rays ([`passes`]).
    pub passes: PassData,
    /// What 0 and 65535 of its depth pass stand for, when one was asked for.
    pub depth_range: Option<[f64; 2]>,
    /// Seconds spent tracing it.
    pub seconds: f64,
}

/// What to render: the recipe, and the count and size when not the recipe's own.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Request {
    /// Whose cameras and lights.
    pub recipe: Recipe,
    /// Views (the recipe's count when `None`).
    pub views: Option<u32>,
    /// Side in pixels (the recipe's when `None`).
    pub size: Option<u32>,
    /// The item's seed: every random draw of its cameras and lights comes from it.
    pub seed: u64,
    /// The passes to render beside each view ([`passes`]; none by default).
    pub passes: PassSet,
}

/// Renders the views `request` asks for of `surface`, placed by `placement`.
pub fn render_views(surface: &Surface<'_>, request: &Request) -> Vec<RenderedView> {
    let recipe = request.recipe;
    let (views, size) = (
        request.views.unwrap_or(recipe.views()),
        request.size.unwrap_or(recipe.size()),
    );
    let mut rng = SplitMix64::new(request.seed);
    let chosen = cameras::trellis_views(views, &mut rng);
    chosen
        .into_iter()
        .map(|view| {
            let lights = match recipe {
                Recipe::Trellis => Lights::trellis(),
                Recipe::Trellis2 => Lights::trellis2(&mut rng),
            };
            let camera = PerspectiveCamera::of_view(&view);
            let start = std::time::Instant::now();
            let (image, passes) =
                picture::trace_with(surface, &camera, &lights, size, request.passes);
            RenderedView {
                view,
                camera,
                image,
                passes,
                depth_range: request
                    .passes
                    .contains(Pass::Depth)
                    .then(|| passes::depth_range(view.radius)),
                seconds: start.elapsed().as_secs_f64(),
            }
        })
        .collect()
}

/// The `transforms.json` of rendered views, as the peers' scripts write it (`aabb`, `scale`,
/// `offset`, and per frame `file_path` `NNN.png`, `camera_angle_x`, `transform_matrix`, and
/// the `depth` `min` and `max` of a depth pass, as TRELLIS's `render.py` writes them).
pub fn transforms_json(placement: &Placement, views: &[RenderedView]) -> String {
    let frames: Vec<String> = views
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let m = v.camera.transform_matrix();
            let rows: Vec<String> = m.iter().map(|r| format!("[{}]", join(r))).collect();
            let depth = v.depth_range.map_or(String::new(), |[lo, hi]| {
                format!(", \"depth\": {{\"min\": {lo:?}, \"max\": {hi:?}}}")
            });
            format!(
                "    {{\"file_path\": \"{i:03}.png\", \"camera_angle_x\": {}, \"transform_matrix\": [{}]{depth}}}",
                v.view.fov,
                rows.join(", ")
            )
        })
        .collect();
    format!(
        "{{\n  \"aabb\": [[-0.5, -0.5, -0.5], [0.5, 0.5, 0.5]],\n  \"scale\": {},\n  \"offset\": [{}],\n  \"frames\": [\n{}\n  ]\n}}\n",
        placement.scale,
        join(&placement.offset),
        frames.join(",\n")
    )
}

fn join(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}
