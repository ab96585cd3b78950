//! The optional passes of a condition view, beside its shaded RGBA, named and laid out as
//! TRELLIS's Blender script writes them (`init_nodes` in
//! `dataset_toolkits/blender_script/render.py`: `NNN_normal`, `NNN_depth`, `NNN_albedo`,
//! beside `NNN.png`), each from the same rays as the view:
//!
//! - `normal`: the surface's normal in the placed (Blender Z-up) world, turned towards the
//!   camera as Cycles turns a back face's, from the ray through the pixel's centre; a 16-bit
//!   RGBA PNG of `(n + 1) / 2`, alpha 65535 where that ray hits and 0 elsewhere (TRELLIS writes
//!   an OpenEXR of `n`; a PNG needs no other reader).
//! - `depth`: the distance from the camera's plane (Blender's Z pass) from the centre ray,
//!   mapped linearly from `[radius − √3/2, radius + √3/2]` onto 16-bit grey as TRELLIS's
//!   `depth_map` node maps it (the range is in the frame's `depth` of `transforms.json`);
//!   65535 where the ray sees nothing.
//! - `albedo`: the base colour before lighting (sRGB, straight), with the view's alpha, the
//!   edges antialiased as the view's are (Blender's `DiffCol` with `Alpha`).
//! - `mask`: the view's alpha as 8-bit grey.

use super::RenderedView;

/// One pass of a view.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Pass {
    /// World-space normals.
    Normal,
    /// Distance from the camera's plane.
    Depth,
    /// Base colour before lighting.
    Albedo,
    /// Coverage.
    Mask,
}

impl Pass {
    /// Every pass, by name, in the order they are written.
    pub const ALL: [(&'static str, Pass); 4] = [
        ("normal", Pass::Normal),
        ("depth", Pass::Depth),
        ("albedo", Pass::Albedo),
        ("mask", Pass::Mask),
    ];

    /// The pass named `name`.
    pub fn named(name: &str) -> Option<Self> {
        Self::ALL.iter().find(|(n, _)| *n == name).map(|(_, p)| *p)
    }

    /// The pass's name, as [`Pass::named`] reads it.
    pub fn name(self) -> &'static str {
        Self::ALL[self as usize].0
    }

    /// The file of view `view`'s pass: `003_normal.png`.
    pub fn file_name(self, view: usize) -> String {
        format!("{view:03}_{}.png", self.name())
    }
}

/// A set of passes (none by default).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PassSet(u8);

impl PassSet {
    /// No pass: the shaded view alone.
    pub const NONE: PassSet = PassSet(0);

    /// The set of `passes`.
    pub fn of(passes: &[Pass]) -> Self {
        Self(passes.iter().fold(0, |bits, &p| bits | 1 << p as u8))
    }

    /// Whether `pass` is in the set.
    pub fn contains(self, pass: Pass) -> bool {
        self.0 & (1 << pass as u8) != 0
    }

    /// The passes in the set, in [`Pass::ALL`]'s order.
    pub fn iter(self) -> impl Iterator<Item = Pass> {
        Pass::ALL
            .into_iter()
            .map(|(_, p)| p)
            .filter(move |&p| self.contains(p))
    }

    /// Whether no pass is asked for.
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
}

/// Half the diagonal of the unit cube the asset is placed in: TRELLIS's depth range is the
/// camera's radius ± this (`render.py`, `spec_nodes['depth_map']`).
pub const DEPTH_HALF_RANGE: f64 = 0.866_025_403_784_438_6;

/// The depth range of a camera at `radius`: what 0 and 65535 of its depth pass stand for.
pub fn depth_range(radius: f64) -> [f64; 2] {
    [radius - DEPTH_HALF_RANGE, radius + DEPTH_HALF_RANGE]
}

/// What the centre ray of a pixel saw, for the passes it feeds.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CentreSample {
    /// Unit normal towards the camera (zero on a miss).
    pub normal: [f32; 3],
    /// Distance from the camera's plane (infinite on a miss).
    pub depth: f32,
}

/// A 16-bit sample of `v` in `[0, 1]`.
fn unit16(v: f64) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

/// The normal pass's pixel of `sample`: `(n + 1) / 2` and alpha.
pub fn normal_pixel(sample: &CentreSample) -> [u16; 4] {
    if sample.depth.is_finite() {
        let [x, y, z] = sample.normal.map(|c| unit16((c as f64 + 1.0) / 2.0));
        [x, y, z, u16::MAX]
    } else {
        [0; 4]
    }
}

/// The depth pass's pixel of `sample` in `range`.
pub fn depth_pixel(sample: &CentreSample, range: [f64; 2]) -> u16 {
    match sample.depth.is_finite() {
        true => unit16((sample.depth as f64 - range[0]) / (range[1] - range[0])),
        false => u16::MAX,
    }
}

/// Pass `pass` of `view` as a PNG file (module docs); an error when the view was traced
/// without what the pass needs.
pub fn encode(pass: Pass, view: &RenderedView) -> Result<Vec<u8>, String> {
    let size = view.image.size;
    let data = &view.passes;
    let missing = || format!("the view was traced without its {} pass", pass.name());
    let encoded = match pass {
        Pass::Normal => {
            check(data.centres.len(), size, 1).ok_or_else(missing)?;
            let samples: Vec<u16> = data.centres.iter().flat_map(normal_pixel).collect();
            crate::encode_png16(size, size, png::ColorType::Rgba, &samples)
        }
        Pass::Depth => {
            check(data.centres.len(), size, 1).ok_or_else(missing)?;
            let range = view.depth_range.ok_or_else(missing)?;
            let samples: Vec<u16> = data.centres.iter().map(|c| depth_pixel(c, range)).collect();
            crate::encode_png16(size, size, png::ColorType::Grayscale, &samples)
        }
        Pass::Albedo => {
            check(data.albedo.len(), size, 4).ok_or_else(missing)?;
            crate::encode_png(size, size, png::ColorType::Rgba, &data.albedo)
        }
        Pass::Mask => {
            let alpha: Vec<u8> = view.image.rgba.chunks(4).map(|p| p[3]).collect();
            crate::encode_png(size, size, png::ColorType::Grayscale, &alpha)
        }
    };
    encoded.map_err(|e| format!("encoding the {} pass as PNG: {e}", pass.name()))
}

/// `Some` when `len` is `per_pixel` values for each pixel of a `size²` view.
fn check(len: usize, size: u32, per_pixel: usize) -> Option<()> {
    (len == size as usize * size as usize * per_pixel && len > 0).then_some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_are_named_and_a_set_lists_them_in_order() {
        for (name, pass) in Pass::ALL {
            assert_eq!(Pass::named(name), Some(pass));
            assert_eq!(pass.name(), name);
        }
        assert_eq!(Pass::named("mist"), None);
        let set = PassSet::of(&[Pass::Mask, Pass::Normal, Pass::Mask]);
        assert_eq!(set.iter().collect::<Vec<_>>(), [Pass::Normal, Pass::Mask]);
        assert!(!set.contains(Pass::Depth) && PassSet::NONE.is_empty());
        assert_eq!(Pass::Albedo.file_name(7), "007_albedo.png");
    }

    #[test]
    fn depth_maps_the_range_onto_16_bits_and_a_miss_to_the_far_end() {
        let range = depth_range(2.0);
        let at = |d: f32| {
            depth_pixel(
                &CentreSample {
                    normal: [0.0, 0.0, 1.0],
                    depth: d,
                },
                range,
            )
        };
        assert_eq!(at(range[0] as f32 - 0.1), 0);
        assert_eq!(at(2.0), 32768);
        assert_eq!(at(f32::INFINITY), u16::MAX);
        let miss = CentreSample {
            normal: [0.0; 3],
            depth: f32::INFINITY,
        };
        assert_eq!(normal_pixel(&miss), [0; 4]);
        let up = CentreSample {
            normal: [0.0, 0.0, 1.0],
            depth: 1.0,
        };
        assert_eq!(normal_pixel(&up), [32768, 32768, 65535, 65535]);
    }
}
