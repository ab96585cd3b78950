//! The names `export` gives items: one rule, used for every consumer (docs/FORMAT.md,
//! "Exports"). An item's stem is its manifest index, zero-padded, then a readable form of its
//! id: `000003-chair_1`; each consumer adds its own suffix or folder (`000003-chair_1.npz`,
//! `000003-chair_1/geo_data/000003-chair_1_surface.npz`). The index makes stems unique per
//! item whatever the ids are (ids differing only in characters a file name cannot hold, or only
//! in case on a case-insensitive file system, still get stems of their own); the readable part
//! only helps a person find a file, and the id itself is stored inside npz files (the `id`
//! entry) and in the export's record.
//!
//! Every stem leaves [`SUFFIX_ROOM`] bytes for a consumer's suffix within [`NAME_MAX`],
//! whatever the id's length: the readable part is cut to fit, which keeps stems unique because
//! the index comes first.

/// The longest file name (bytes) Linux file systems accept (ext4, xfs, btrfs, tmpfs: `NAME_MAX`).
pub const NAME_MAX: usize = 255;

/// Bytes left after a stem for a consumer's suffix (`_surface.npz` is 12).
pub const SUFFIX_ROOM: usize = 16;

/// Digits the index is padded to at least, so that names sort in manifest order.
const MIN_INDEX_DIGITS: usize = 6;

/// The names of one job's exported items.
#[derive(Debug, Clone, Copy)]
pub struct ExportNames {
    /// Digits of the index: enough for the job's last item, at least [`MIN_INDEX_DIGITS`].
    width: usize,
}

impl ExportNames {
    /// The naming of a job with `items` items (its frozen manifest's length).
    pub fn for_job(items: u64) -> Self {
        let digits = items.saturating_sub(1).to_string().len();
        Self {
            width: digits.max(MIN_INDEX_DIGITS),
        }
    }

    /// The stem of the item at manifest position `index` with id `id`: `{index}-{readable}`,
    /// at most `NAME_MAX − SUFFIX_ROOM` bytes.
    pub fn stem(&self, index: u64, id: &str) -> String {
        let prefix = format!("{index:0width$}-", width = self.width);
        let room = (NAME_MAX - SUFFIX_ROOM).saturating_sub(prefix.len());
        let mut readable = readable_stem(id);
        // The readable part is ASCII, so any byte count is a character boundary.
        readable.truncate(room);
        format!("{prefix}{readable}")
    }
}

/// The id with every character outside `[A-Za-z0-9._-]` replaced by `_`: readable, and safe
/// in any file system and shell. Not unique on its own (the index is).
fn readable_stem(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    #[test]
    fn ids_that_share_a_readable_form_get_stems_of_their_own() {
        let names = ExportNames::for_job(5);
        let ids = [
            "chair/1", "chair 1", "chair_1", "椅子", "桌子", "Chair_1", "CHAIR_1",
        ];
        let stems: Vec<String> = ids
            .iter()
            .enumerate()
            .map(|(i, id)| names.stem(i as u64, id))
            .collect();
        assert_eq!(stems[0], "000000-chair_1");
        assert_eq!(stems[3], "000003-__");
        // Unique even where the file system ignores case.
        let folded: BTreeSet<String> = stems.iter().map(|f| f.to_lowercase()).collect();
        assert_eq!(folded.len(), ids.len());
    }

    #[test]
    fn every_stem_leaves_room_for_a_suffix_whatever_the_id_length() {
        let names = ExportNames::for_job(20_000_000);
        for len in (0..300).chain([1000, 100_000]) {
            for unit in ["a", "é", "椅", "/"] {
                let stem = names.stem(12_345_678, &unit.repeat(len));
                assert!(
                    stem.len() + SUFFIX_ROOM <= NAME_MAX,
                    "{len} × {unit}: {}",
                    stem.len()
                );
                assert!(stem.starts_with("12345678-"), "{stem}");
            }
        }
        // Two long ids that differ only past the cut still differ by index.
        assert_ne!(
            names.stem(1, &"x".repeat(400)),
            names.stem(2, &"x".repeat(401))
        );
    }

    #[test]
    fn stems_sort_in_manifest_order() {
        let small = ExportNames::for_job(3);
        assert!(small.stem(9, "b") < small.stem(10, "a"));
        let big = ExportNames::for_job(12_000_000);
        assert_eq!(big.stem(7, "a"), "00000007-a");
        assert!(big.stem(999_999, "z") < big.stem(10_000_000, "a"));
    }
}
