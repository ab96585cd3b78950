//! Wavefront MTL material libraries, mapped onto metallic-roughness materials.
//!
//! Read: `Kd` (base colour), `d` and `Tr` (alpha, `d` first; below 1 makes the material
//! BLEND), `Pr`/`Pm` and `map_Pr`/`map_Pm` (the PBR extension of MTL), `Ns` (roughness when
//! `Pr` is absent, as Blender's OBJ importer maps it: `1 − √(Ns/1000)`, clamped to [0, 1]),
//! `map_Kd`, `map_d`, and the map options `-o` (offset), `-s` (scale) and `-clamp`. MTL
//! colours are taken as sRGB values, as three.js's MTL loader reads them: they were written
//! for display without colour management. Named as not read: bump, normal, displacement,
//! specular, emissive and reflection maps, and a non-black emissive colour `Ke`.

pub use crate::colour::srgb_to_linear;

use super::{AlphaMode, Facts, Material, ScalarMap, TextureRef, Wrap, IDENTITY_UV};

/// A map statement's options and file.
#[derive(Debug, Clone, PartialEq)]
pub struct MapSpec {
    /// The file, relative to the MTL file's folder.
    pub file: String,
    /// Coordinate transform (`-o`, `-s`).
    pub transform: [[f32; 3]; 2],
    /// `-clamp on`.
    pub clamp: bool,
}

/// Which texture a map statement fills.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// `map_Kd`.
    BaseColor,
    /// `map_d`.
    Alpha,
    /// `map_Pr`.
    Roughness,
    /// `map_Pm`.
    Metallic,
}

/// A parsed MTL material: the material with its maps not yet bound to images.
#[derive(Debug, Clone)]
pub struct MtlMaterial {
    /// The material's factors.
    pub material: Material,
    /// Its maps.
    pub maps: Vec<(Slot, MapSpec)>,
}

/// Parses the numbers after a keyword; missing or bad ones are `None`.
fn numbers(rest: &[&str]) -> Vec<Option<f32>> {
    rest.iter().map(|w| w.parse::<f32>().ok()).collect()
}

/// Parses a map statement's options and file name (the rest of the line after the options).
fn map_spec(words: &[&str]) -> Option<MapSpec> {
    let mut spec = MapSpec {
        file: String::new(),
        transform: IDENTITY_UV,
        clamp: false,
    };
    let mut i = 0;
    while i < words.len() && words[i].starts_with('-') {
        let opt = words[i];
        let args = words[i + 1..]
            .iter()
            .take_while(|w| w.parse::<f32>().is_ok())
            .count();
        match opt {
            "-o" | "-s" => {
                let v = numbers(&words[i + 1..i + 1 + args.min(3)]);
                let get = |k: usize, d: f32| v.get(k).copied().flatten().unwrap_or(d);
                let (col, d) = if opt == "-o" { (2, 0.0) } else { (0, 1.0) };
                spec.transform[0][col] = get(0, d);
                spec.transform[1][if col == 2 { 2 } else { 1 }] = get(1, d);
                i += 1 + args.min(3);
            }
            "-clamp" => {
                spec.clamp = words.get(i + 1) == Some(&"on");
                i += 2;
            }
            "-mm" => i += 1 + args.min(2),
            "-t" => i += 1 + args.min(3),
            _ => i += 2,
        }
    }
    let file = words.get(i..)?.join(" ");
    (!file.is_empty()).then_some(MapSpec { file, ..spec })
}

impl MapSpec {
    /// The texture reference of this map once its image is `image`. OBJ's `v` runs up the
    /// image, glTF's (ours) down it: the flip `v ↦ 1 − v` follows the map's own transform.
    pub fn bind(&self, image: usize) -> TextureRef {
        let [a, b] = self.transform;
        TextureRef {
            transform: [a, [-b[0], -b[1], 1.0 - b[2]]],
            wrap: [if self.clamp {
                Wrap::Clamp
            } else {
                Wrap::Repeat
            }; 2],
            ..TextureRef::plain(image)
        }
    }
}

/// Applies one statement to `m`; unread features are named in `facts` under `label`.
fn statement(m: &mut MtlMaterial, key: &str, rest: &[&str], facts: &mut Facts) {
    let v = numbers(rest);
    let first = v.first().copied().flatten();
    let label = format!("MTL material `{}`", super::sibling::clip(&m.material.name));
    match key {
        "Kd" => {
            if let [Some(r), Some(g), Some(b), ..] = v[..] {
                let c = [r, g, b].map(|c| srgb_to_linear(c.clamp(0.0, 1.0)));
                m.material.base_color = [c[0], c[1], c[2], m.material.base_color[3]];
            }
        }
        "d" => {
            if let Some(d) = first {
                m.material.base_color[3] = d.clamp(0.0, 1.0);
            }
        }
        "Tr" => {
            if let Some(t) = first {
                m.material.base_color[3] = (1.0 - t).clamp(0.0, 1.0);
            }
        }
        "Pr" => m.material.roughness = first.unwrap_or(m.material.roughness).clamp(0.0, 1.0),
        "Pm" => m.material.metallic = first.unwrap_or(m.material.metallic).clamp(0.0, 1.0),
        "Ns" => {
            if let Some(ns) = first {
                // Blender's OBJ importer (io/wavefront_obj, obj_import_mtl.cc).
                m.material.roughness =
                    (1.0 - (ns.clamp(0.0, 1000.0) / 1000.0).sqrt()).clamp(0.0, 1.0);
            }
        }
        "map_Kd" | "map_d" | "map_Pr" | "map_Pm" => {
            let slot = match key {
                "map_Kd" => Slot::BaseColor,
                "map_d" => Slot::Alpha,
                "map_Pr" => Slot::Roughness,
                _ => Slot::Metallic,
            };
            match map_spec(rest) {
                Some(spec) => m.maps.push((slot, spec)),
                None => facts.skip(format!("{label}: {key} without a file")),
            }
        }
        "map_Ks" | "map_Ns" | "map_bump" | "map_Bump" | "bump" | "norm" | "disp" | "decal"
        | "refl" | "map_Ke" | "map_Ka" => facts.skip(format!("{label}: {key}")),
        "Ke" if v.iter().any(|x| x.is_some_and(|x| x > 0.0)) => {
            facts.skip(format!("{label}: emissive colour Ke"))
        }
        _ => {}
    }
}

/// Parses an MTL file's text into its materials, in order (a repeated name keeps the first).
pub fn parse(text: &str, facts: &mut Facts) -> Vec<MtlMaterial> {
    let mut out: Vec<MtlMaterial> = Vec::new();
    // `Pr` wins over `Ns`, and `d` over `Tr`, whatever their order.
    let (mut pr_seen, mut d_seen) = (false, false);
    for line in text.lines() {
        let line = line.split('#').next().unwrap_or("").trim();
        let words: Vec<&str> = line.split_whitespace().collect();
        let Some((&key, rest)) = words.split_first() else {
            continue;
        };
        if key == "newmtl" {
            let mut material = Material::default_for(false);
            material.name = rest.join(" ");
            out.push(MtlMaterial {
                material,
                maps: Vec::new(),
            });
            (pr_seen, d_seen) = (false, false);
            continue;
        }
        let Some(m) = out.last_mut() else {
            continue;
        };
        pr_seen |= key == "Pr";
        d_seen |= key == "d";
        if (key == "Ns" && pr_seen) || (key == "Tr" && d_seen) {
            continue;
        }
        statement(m, key, rest, facts);
    }
    for m in &mut out {
        let alpha_mapped = m.maps.iter().any(|(s, _)| *s == Slot::Alpha);
        if m.material.base_color[3] < 1.0 || alpha_mapped {
            m.material.alpha_mode = AlphaMode::Blend;
        }
    }
    out
}

/// The scalar map of `slot` bound to `image`, reading `channel`.
pub fn scalar(spec: &MapSpec, image: usize, channel: usize) -> ScalarMap {
    ScalarMap {
        texture: spec.bind(image),
        channel,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kd_d_pr_pm_and_maps_are_read() {
        let mut facts = Facts::default();
        let text =
            "newmtl red\nKd 1 0 0\nd 0.5\nPr 0.25\nPm 1\nmap_Kd -o 0.5 0.25 -s 2 2 tex/a b.png\n\
                    map_Bump n.png\nnewmtl plain\nKd 0.5 0.5 0.5\nNs 250\n";
        let ms = parse(text, &mut facts);
        assert_eq!(ms.len(), 2);
        let red = &ms[0];
        assert_eq!(red.material.base_color, [1.0, 0.0, 0.0, 0.5]);
        assert_eq!(red.material.alpha_mode, AlphaMode::Blend);
        assert_eq!((red.material.roughness, red.material.metallic), (0.25, 1.0));
        let (slot, spec) = &red.maps[0];
        assert_eq!(*slot, Slot::BaseColor);
        assert_eq!(spec.file, "tex/a b.png");
        assert_eq!(spec.transform, [[2.0, 0.0, 0.5], [0.0, 2.0, 0.25]]);
        let plain = &ms[1].material;
        assert!((plain.base_color[0] - srgb_to_linear(0.5)).abs() < 1e-6);
        assert!((plain.roughness - 0.5).abs() < 1e-6, "{}", plain.roughness);
        assert_eq!(plain.alpha_mode, AlphaMode::Opaque);
        assert_eq!(facts.not_read, ["MTL material `red`: map_Bump"]);
    }
}
