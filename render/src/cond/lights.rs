//! Lighting that approximates the peers' Blender rigs with a diffuse term per light and no
//! shadows (docs/RENDERS.md says where this differs from Cycles):
//!
//! - TRELLIS (`dataset_toolkits/blender_script/render.py` `init_lighting`): a point light at
//!   (4, 1, 6), a wide area light above (z = 10) and a weaker one below (z = −10), on a
//!   transparent film: here an ambient share plus the key, top and bottom directions.
//! - TRELLIS.2 (`data_toolkit/blender_script/render_cond.py` `init_random_lighting`): a white
//!   world and 1–3 point lights per view, each in a random direction leaning upwards
//!   (`randn(3)` with 0.6 added to z), its strength a random share of what is left of 1.5:
//!   here the world is an ambient term and each light a direction drawn the same way, its
//!   share drawn as theirs (`sqrt(uniform(0.01, 1))` of what is left), from our seeded
//!   generator.

use super::rng::SplitMix64;
use glam::{DVec3, Vec3A};

/// Directional lights plus an ambient term, as a multiplier of the albedo (linear).
#[derive(Debug, Clone, PartialEq)]
pub struct Lights {
    /// Light from every direction (a white world, the wide area lights' spill).
    pub ambient: f32,
    /// Unit directions towards each light, with its weight.
    pub directions: Vec<(Vec3A, f32)>,
    /// A point light's position, with its weight (the key light of TRELLIS).
    pub points: Vec<(DVec3, f32)>,
}

impl Lights {
    /// TRELLIS's three lights.
    pub fn trellis() -> Self {
        Self {
            ambient: 0.30,
            directions: vec![(Vec3A::Z, 0.40), (Vec3A::NEG_Z, 0.10)],
            points: vec![(DVec3::new(4.0, 1.0, 6.0), 0.50)],
        }
    }

    /// TRELLIS.2's white world and 1–3 random lights, drawn from `rng`.
    pub fn trellis2(rng: &mut SplitMix64) -> Self {
        let count = 1 + (rng.next_u64() % 3) as usize;
        let mut left = 1.5f64;
        let mut directions = Vec::with_capacity(count);
        for _ in 0..count {
            let d = DVec3::new(normal(rng), normal(rng), normal(rng) + 0.6).normalize_or(DVec3::Z);
            let share = (0.01 + 0.99 * rng.uniform()).sqrt() * left;
            left -= share * 0.5;
            directions.push((d.as_vec3a(), (share / 1.5 * 0.6) as f32));
        }
        Self {
            ambient: 0.65,
            directions,
            points: Vec::new(),
        }
    }

    /// The light falling on a surface of unit `normal` at `point`.
    pub fn at(&self, normal: Vec3A, point: DVec3) -> f32 {
        let mut light = self.ambient;
        for (d, w) in &self.directions {
            light += w * normal.dot(*d).max(0.0);
        }
        for (p, w) in &self.points {
            let d = (*p - point).normalize_or(DVec3::Z).as_vec3a();
            light += w * normal.dot(d).max(0.0);
        }
        light
    }
}

/// A normal deviate (Box–Muller).
fn normal(rng: &mut SplitMix64) -> f64 {
    let (u, v) = (rng.uniform().max(1e-300), rng.uniform());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lit_from_above_more_than_from_below_and_drawn_per_seed() {
        let t = Lights::trellis();
        let p = DVec3::ZERO;
        assert!(t.at(Vec3A::Z, p) > t.at(Vec3A::NEG_Z, p));
        assert!(t.at(Vec3A::NEG_Z, p) >= t.ambient);
        let a = Lights::trellis2(&mut SplitMix64::new(5));
        assert_eq!(a, Lights::trellis2(&mut SplitMix64::new(5)));
        assert!((1..=3).contains(&a.directions.len()));
        assert!(a
            .directions
            .iter()
            .all(|(d, w)| (d.length() - 1.0).abs() < 1e-5 && *w > 0.0));
    }
}
