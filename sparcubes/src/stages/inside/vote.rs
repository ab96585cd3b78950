//! The winding-number vote of the inside test: the median |w| at a few points of a region
//! (or of a group of sealed vertices, or a sealed pocket), and what it says.

use crate::queries::winding::WindingTree;

/// Winding numbers sampled per region (or per sealed group of vertices); the median decides.
pub const SAMPLES: usize = 3;

/// |w| at or below which a region is air.
pub const AIR_UP_TO: f64 = 0.25;

/// |w| at or above which a region is solid.
pub const SOLID_FROM: f64 = 0.75;

/// What the winding number says of a region.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// |w| ≥ [`SOLID_FROM`]: material.
    Solid,
    /// |w| ≤ [`AIR_UP_TO`]: empty space.
    Air,
    /// In between: the caller keeps the answer the grid alone gives.
    Ambiguous,
    /// A region sealed behind small openings (docs/ALGORITHM.md §4) that is not read as
    /// solid here: back to the outside, the answer of the grid's exact flood.
    Unsealed,
}

/// The verdict for a (median) winding number.
pub fn verdict(w: f64) -> Verdict {
    let w = w.abs();
    if w >= SOLID_FROM {
        Verdict::Solid
    } else if w <= AIR_UP_TO {
        Verdict::Air
    } else {
        Verdict::Ambiguous
    }
}

/// The median of |w| at the given points (empty: 0); `stack` is the queries' scratch space.
pub fn median_winding(tree: &WindingTree, points: &[[f64; 3]], stack: &mut Vec<u32>) -> f64 {
    let mut w: Vec<f64> = points
        .iter()
        .map(|&p| tree.winding_number_with(p, stack).abs())
        .collect();
    median(&mut w)
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let m = values.len() / 2;
    if values.len() % 2 == 1 {
        values[m]
    } else {
        0.5 * (values[m - 1] + values[m])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn verdicts_follow_the_thresholds() {
        assert_eq!(verdict(0.02), Verdict::Air);
        assert_eq!(verdict(-0.98), Verdict::Solid);
        assert_eq!(verdict(2.0), Verdict::Solid);
        assert_eq!(verdict(0.5), Verdict::Ambiguous);
        assert_eq!(verdict(AIR_UP_TO), Verdict::Air);
        assert_eq!(verdict(SOLID_FROM), Verdict::Solid);
    }
}
