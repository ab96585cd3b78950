//! Appearance in: the source's materials, textures and vertex colours, read beside its geometry.
//!
//! [`read`] parses the same bytes [`crate::io`] read the shape from, a second time, into an
//! [`Appearance`]: the surface as triangles with their texture coordinates, vertex colours
//! and material, the materials (glTF 2.0 metallic-roughness, or what an OBJ's MTL says
//! mapped onto it), the decoded images, and [`Facts`] about them, including every feature
//! that was not read. The shape's loader is left as it is: a job without `[attributes]`
//! runs exactly the code it ran before, and the appearance never changes the geometry.
//!
//! Nothing here fails an item for a texture: an image that cannot be read (missing,
//! truncated, corrupt, too large) is named in [`Facts::not_read`] and its material keeps
//! its factors. A file whose appearance cannot be parsed at all fails with the parse error.
//!
//! Colours are linear RGBA in `[0, 1]`; images stay 8-bit as decoded (sRGB for base colour,
//! linear for data), their decoding is [`crate::attributes`]' job when sampled.

mod budget;
mod gltf;
mod gltf_check;
mod gltf_images;
pub mod image;
mod mtl;
mod obj;
mod off;
mod ply;
pub mod references;
mod sibling;

pub use budget::TextureBudget;
pub use image::Image;
pub use mtl::srgb_to_linear;

use crate::error::{Error, Result};
use crate::io::{Buffers, Format};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

/// Marks a corner-channel entry of a triangle that has no value there.
pub const NONE: u32 = u32::MAX;

/// A per-corner attribute of the surface: `values`, and for every triangle the index of the
/// value at each corner (all [`NONE`] when that triangle lacks the attribute). Empty when no
/// triangle has it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Channel<T> {
    /// The distinct values.
    pub values: Vec<T>,
    /// Per triangle, the value index at each corner; empty, or parallel to the triangles.
    pub corners: Vec<[u32; 3]>,
}

impl<T: Copy> Channel<T> {
    /// The three corner values of triangle `t`, when it has them.
    pub fn at(&self, t: usize) -> Option<[T; 3]> {
        let c = self.corners.get(t)?;
        let get = |i: u32| self.values.get(i as usize).copied();
        Some([get(c[0])?, get(c[1])?, get(c[2])?])
    }

    /// Appends the corners of one more triangle, first padding the triangles before it.
    pub(crate) fn push(&mut self, triangle: usize, corners: [u32; 3]) {
        if self.corners.len() < triangle {
            self.corners.resize(triangle, [NONE; 3]);
        }
        self.corners.push(corners);
    }

    /// Pads the corners to `triangles` entries when the channel is used at all.
    pub(crate) fn finish(&mut self, triangles: usize) {
        if !self.corners.is_empty() {
            self.corners.resize(triangles, [NONE; 3]);
        }
    }
}

/// The source surface with what its appearance needs, in the source frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Triangles as indices into `positions`.
    pub triangles: Vec<[u32; 3]>,
    /// Material of each triangle (an index into [`Appearance::materials`]).
    pub material: Vec<u32>,
    /// Texture coordinate sets 0 and 1 (glTF `TEXCOORD_0`/`_1`; OBJ `vt` is set 0).
    pub uv: [Channel<[f32; 2]>; 2],
    /// Vertex colours, linear RGBA (glTF `COLOR_0`, PLY and OFF colours, OBJ `v x y z r g b`).
    pub color: Channel<[f32; 4]>,
}

/// How a texture's coordinates wrap outside `[0, 1]` (glTF sampler `wrapS`/`wrapT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Wrap {
    /// Tiles (glTF's default, and every MTL map's).
    #[default]
    Repeat,
    /// Clamps to the edge texel.
    Clamp,
    /// Tiles, every other tile mirrored.
    Mirror,
}

/// A texture used by a material: which image, which texture coordinate set, the transform
/// applied to those coordinates, and the sampler.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TextureRef {
    /// Index into [`Appearance::images`].
    pub image: usize,
    /// Texture coordinate set (0 or 1).
    pub set: usize,
    /// Affine map of the coordinates, `uv' = [m00 m01 m02; m10 m11 m12] · (u, v, 1)`
    /// (glTF `KHR_texture_transform`; identity otherwise).
    pub transform: [[f32; 3]; 2],
    /// Wrap along u and v.
    pub wrap: [Wrap; 2],
    /// Magnification by nearest texel (glTF `magFilter` NEAREST) rather than bilinear.
    pub nearest: bool,
}

/// The identity texture-coordinate transform.
pub const IDENTITY_UV: [[f32; 3]; 2] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

impl TextureRef {
    /// A texture of `image` on coordinate set 0, untransformed, repeating, bilinear.
    pub fn plain(image: usize) -> Self {
        Self {
            image,
            set: 0,
            transform: IDENTITY_UV,
            wrap: [Wrap::Repeat; 2],
            nearest: false,
        }
    }
}

/// How a material's alpha is used (glTF `alphaMode`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface is opaque (stored alpha 255).
    #[default]
    Opaque,
    /// Alpha below the cutoff is fully transparent, at or above it fully opaque.
    Mask(f32),
    /// Alpha is the coverage.
    Blend,
}

impl AlphaMode {
    /// The glTF name of the mode.
    pub fn name(self) -> &'static str {
        match self {
            AlphaMode::Opaque => "OPAQUE",
            AlphaMode::Mask(_) => "MASK",
            AlphaMode::Blend => "BLEND",
        }
    }
}

/// One channel of a texture read as a scalar (metallic, roughness, alpha).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalarMap {
    /// The texture.
    pub texture: TextureRef,
    /// Which channel: 0 red, 1 green, 2 blue, 3 alpha.
    pub channel: usize,
}

/// A metallic-roughness material: factors, each optionally multiplied by a texture.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Its name in the file (empty when none).
    pub name: String,
    /// Base colour factor, linear RGBA.
    pub base_color: [f32; 4],
    /// Base colour texture (sRGB RGB, linear alpha).
    pub base_color_map: Option<TextureRef>,
    /// Metallic factor.
    pub metallic: f32,
    /// Metallic texture channel (glTF: blue of `metallicRoughnessTexture`).
    pub metallic_map: Option<ScalarMap>,
    /// Roughness factor.
    pub roughness: f32,
    /// Roughness texture channel (glTF: green of `metallicRoughnessTexture`).
    pub roughness_map: Option<ScalarMap>,
    /// Alpha texture beside the base colour's alpha (MTL `map_d`).
    pub alpha_map: Option<ScalarMap>,
    /// How alpha is used.
    pub alpha_mode: AlphaMode,
}

/// Base colour of a surface without any material or colour: 0.8 linear grey, the base colour
/// of Blender's default Principled BSDF (so an uncoloured item looks as it does in Blender, in
/// which the data toolkits of the generators we export for render their assets: docs/FORMAT.md,
/// "Attributes"), rather than glTF's white.
pub const DEFAULT_BASE_COLOR: f32 = 0.8;
/// Roughness of the default material: 0.5, Blender's Principled BSDF default.
pub const DEFAULT_ROUGHNESS: f32 = 0.5;

impl Material {
    /// The material of a surface that names none: a dielectric (metallic 0: glTF's default
    /// of 1 would call every unpainted STL a metal) of base colour [`DEFAULT_BASE_COLOR`]
    /// and roughness [`DEFAULT_ROUGHNESS`], opaque. With vertex colours the base colour
    /// factor is white, so the colours are stored as they are.
    pub fn default_for(vertex_colors: bool) -> Self {
        let grey = if vertex_colors {
            1.0
        } else {
            DEFAULT_BASE_COLOR
        };
        Self {
            name: String::new(),
            base_color: [grey, grey, grey, 1.0],
            base_color_map: None,
            metallic: 0.0,
            metallic_map: None,
            roughness: DEFAULT_ROUGHNESS,
            roughness_map: None,
            alpha_map: None,
            alpha_mode: AlphaMode::Opaque,
        }
    }

    /// The textures the material uses.
    pub fn textures(&self) -> impl Iterator<Item = TextureRef> + '_ {
        let scalar = |m: &Option<ScalarMap>| m.map(|m| m.texture);
        [
            self.base_color_map,
            scalar(&self.metallic_map),
            scalar(&self.roughness_map),
            scalar(&self.alpha_map),
        ]
        .into_iter()
        .flatten()
    }
}

/// What an item's appearance is made of, stored with its row.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Facts {
    /// Materials the file defines and the surface uses (the default one not counted).
    pub materials: u32,
    /// Images decoded and used by a material.
    pub textures: u32,
    /// Largest side of those images, in pixels (0 without any).
    pub largest_texture: u32,
    /// Alpha modes of the materials used, in glTF's names, sorted, without repeats.
    pub alpha_modes: Vec<String>,
    /// Whether the surface carries vertex colours.
    pub vertex_colors: bool,
    /// Features present in the file that were not read, each with where it is (a material,
    /// an image, an extension), sorted, without repeats.
    pub not_read: Vec<String>,
}

impl Facts {
    /// Whether any texture was read.
    pub fn textured(&self) -> bool {
        self.textures > 0
    }

    /// Records a feature that was not read.
    pub(crate) fn skip(&mut self, what: impl Into<String>) {
        self.not_read.push(what.into());
    }
}

/// The appearance of a source: its surface, materials and images, and what they are.
#[derive(Debug, Clone, Default)]
pub struct Appearance {
    /// The surface with texture coordinates, colours and materials.
    pub surface: Surface,
    /// The materials; every triangle's material index is below its length.
    pub materials: Vec<Material>,
    /// The decoded images (an image that could not be decoded is `None`, and named in the
    /// facts).
    pub images: Vec<Option<Image>>,
    /// What was read and what was not.
    pub facts: Facts,
}

impl Appearance {
    /// Settles what the readers left open: a default material for triangles without one,
    /// channels padded to every triangle, the facts counted and sorted, then textures whose
    /// image failed (or was not decoded, as nothing samples it) dropped from their materials.
    fn finish(mut self) -> Self {
        let n = self.surface.triangles.len();
        let default = self.materials.len() as u32;
        let colored = !self.surface.color.corners.is_empty();
        self.surface.material.resize(n, default);
        if self.surface.material.contains(&default) {
            self.materials.push(Material::default_for(colored));
        }
        for uv in &mut self.surface.uv {
            uv.finish(n);
        }
        self.surface.color.finish(n);
        // Counted first: a texture that is not sampled has no image decoded either, and is
        // named as not sampled before it is dropped.
        self.count_facts(colored);
        for m in &mut self.materials {
            drop_missing_textures(m, &self.images);
        }
        self
    }

    /// Fills in the counts of [`Facts`] from the materials the surface uses. A texture counts
    /// only where it can be sampled: a material's texture on a coordinate set none of its
    /// triangles has (coordinates that could not be read, or never given) is named as not
    /// read instead, so an item is `textured` only when a texel is sampled (issue 64 item 6).
    fn count_facts(&mut self, colored: bool) {
        let sets = self.coordinate_sets();
        let mut images: Vec<usize> = Vec::new();
        for (m, has) in self.materials.iter().zip(&sets) {
            let Some(has) = has else { continue };
            for t in m.textures() {
                if has[t.set.min(1)] {
                    // An image that failed to decode is named where it failed.
                    if self.images.get(t.image).is_some_and(Option::is_some) {
                        images.push(t.image);
                    }
                } else {
                    self.facts.skip(format!(
                        "material `{}`: its texture of image {} has no TEXCOORD_{} on its \
                         triangles, so it is not sampled",
                        sibling::clip(&m.name),
                        t.image,
                        t.set
                    ));
                }
            }
        }
        images.sort_unstable();
        images.dedup();
        let in_use = || {
            self.materials
                .iter()
                .zip(&sets)
                .filter(|(_, s)| s.is_some())
                .map(|(m, _)| m)
        };
        let facts = &mut self.facts;
        facts.materials = in_use().filter(|m| !m.name.is_empty()).count() as u32;
        facts.textures = images.len() as u32;
        facts.largest_texture = images
            .iter()
            .filter_map(|&i| self.images.get(i)?.as_ref())
            .map(|im| im.width.max(im.height))
            .max()
            .unwrap_or(0);
        let mut modes: Vec<String> = in_use().map(|m| m.alpha_mode.name().to_string()).collect();
        modes.sort();
        modes.dedup();
        facts.alpha_modes = modes;
        facts.vertex_colors = colored;
        facts.not_read.sort();
        facts.not_read.dedup();
    }

    /// For each material, `None` when no triangle uses it, else whether any of its triangles
    /// has texture coordinates of set 0 and of set 1.
    pub(crate) fn coordinate_sets(&self) -> Vec<Option<[bool; 2]>> {
        let mut sets = vec![None; self.materials.len()];
        for (t, &m) in self.surface.material.iter().enumerate() {
            if let Some(s) = sets.get_mut(m as usize) {
                let has: &mut [bool; 2] = s.get_or_insert([false; 2]);
                for (k, h) in has.iter_mut().enumerate() {
                    *h = *h || self.surface.uv[k].at(t).is_some();
                }
            }
        }
        sets
    }
}

/// Removes from `m` every texture whose image is missing or failed to decode.
fn drop_missing_textures(m: &mut Material, images: &[Option<Image>]) {
    let ok = |t: &TextureRef| images.get(t.image).is_some_and(|i| i.is_some());
    if m.base_color_map.as_ref().is_some_and(|t| !ok(t)) {
        m.base_color_map = None;
    }
    for map in [&mut m.metallic_map, &mut m.roughness_map, &mut m.alpha_map] {
        if map.as_ref().is_some_and(|s| !ok(&s.texture)) {
            *map = None;
        }
    }
}

/// Reads the appearance of a mesh file from its bytes (the bytes [`crate::io::read_source`]
/// read); `path` names it in errors and locates images and material libraries beside it,
/// read from disk or through `buffers`. Formats without appearance (STL) give the surface
/// with the default material. Textures are decoded within the default item's budget
/// ([`TextureBudget::default`]); [`read_within`] takes another.
pub fn read(bytes: &[u8], path: &Path, buffers: Buffers) -> Result<Appearance> {
    read_within(bytes, path, buffers, TextureBudget::default())
}

/// [`read`], decoding textures until `budget` is spent: images past it are named in the
/// facts and not decoded.
pub fn read_within(
    bytes: &[u8],
    path: &Path,
    buffers: Buffers,
    budget: TextureBudget,
) -> Result<Appearance> {
    let format = Format::from_extension(path)
        .or_else(|| Format::sniff(bytes))
        .ok_or_else(|| Error::UnsupportedFormat {
            path: path.to_path_buf(),
            reason: "unknown format: no appearance to read".into(),
        })?;
    let read = catch_unwind(AssertUnwindSafe(|| match format {
        Format::Gltf => gltf::read(bytes, path, buffers, budget),
        Format::Obj => obj::read(bytes, path, buffers, budget),
        Format::Ply => ply::read(bytes, path),
        Format::Off => off::read(bytes, path),
        Format::Stl => stl_surface(bytes, path),
    }))
    .map_err(|_| crate::io::parse_err(path, "the appearance reader failed (a panic)"))?;
    Ok(read?.finish())
}

/// An STL file's surface with the default material (STL has no standard colour; the
/// facet-colour conventions of some exporters in the attribute bytes are not read).
fn stl_surface(bytes: &[u8], path: &Path) -> Result<Appearance> {
    let loaded = crate::io::load_bytes(bytes, Format::Stl, path)?;
    let mut out = Appearance::default();
    out.surface.positions = loaded.mesh.positions;
    out.surface.triangles = loaded.mesh.triangles;
    let binary = bytes.len() >= 84 && !bytes.starts_with(b"solid");
    let colored = binary
        && bytes[84..]
            .chunks_exact(50)
            .any(|facet| facet[48] != 0 || facet[49] != 0);
    if colored {
        out.facts
            .skip("STL facet colours in the attribute bytes (no standard meaning)");
    }
    Ok(out)
}
