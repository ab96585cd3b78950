//! Dropping triangles that repeat another one: the same three vertex indices, in any order.
//!
//! Some files list one face many times (a polygon repeated along a long line, a part exported
//! twice into the same vertex list). The copies add nothing to the surface but every stage
//! pays for each of them, so loading keeps the first of each and counts the rest
//! ([`crate::io::LoadStats::faces_duplicate`]). Triangles are compared by vertex index, so
//! copies with their own vertices at the same positions are only found where the loader
//! welds (STL).

use rayon::prelude::*;

/// Removes every triangle whose three indices (as a set, whatever the order or winding) equal
/// those of an earlier triangle, keeping the order of the others; returns how many went.
///
/// A parallel sort of the keys with their positions: the same result whatever the thread
/// count, and no hashing.
pub fn drop_duplicate_faces(triangles: &mut Vec<[u32; 3]>) -> u64 {
    if triangles.len() < 2 {
        return 0;
    }
    // [lowest, middle, highest index, position]: sorted, copies sit together with the first
    // one ahead.
    let mut keys: Vec<[u32; 4]> = triangles
        .par_iter()
        .enumerate()
        .map(|(i, t)| {
            let mut k = *t;
            k.sort_unstable();
            [k[0], k[1], k[2], i as u32]
        })
        .collect();
    keys.par_sort_unstable();
    let copies: Vec<u32> = keys
        .par_windows(2)
        .filter(|w| w[0][..3] == w[1][..3])
        .map(|w| w[1][3])
        .collect();
    if copies.is_empty() {
        return 0;
    }
    drop(keys);
    let mut drop_mask = vec![false; triangles.len()];
    for &i in &copies {
        drop_mask[i as usize] = true;
    }
    let mut i = 0;
    triangles.retain(|_| {
        i += 1;
        !drop_mask[i - 1]
    });
    copies.len() as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_in_any_order_go_and_the_first_stays() {
        let mut t = vec![
            [0, 1, 2],
            [1, 2, 3],
            [2, 0, 1], // same as the first, rotated
            [0, 2, 1], // same indices, other winding
            [3, 2, 1],
            [1, 2, 4],
        ];
        assert_eq!(drop_duplicate_faces(&mut t), 3);
        assert_eq!(t, vec![[0, 1, 2], [1, 2, 3], [1, 2, 4]]);
    }

    #[test]
    fn a_mesh_without_copies_is_untouched() {
        let mut t = vec![[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]];
        let before = t.clone();
        assert_eq!(drop_duplicate_faces(&mut t), 0);
        assert_eq!(t, before);
    }
}
