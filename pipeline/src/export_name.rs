//! The file names `export` gives items: one rule, used for every format (docs/FORMAT.md,
//! "Exports"). A name is the item's manifest index, zero-padded, then a readable stem made
//! from its id: `000003-chair_1.npz`. The index makes names unique per item whatever the ids
//! are (ids differing only in characters a file name cannot hold, or only in case on a
//! case-insensitive file system, still get names of their own); the stem only helps a person
//! find a file, and the id itself is stored inside it (the `id` entry).
//!
//! Every name, final or temporary (`.NAME.PID.tmp`), fits in [`NAME_MAX`] bytes whatever the
//! id's length: the stem is cut to fit, which keeps names unique because the index comes first.

/// The longest file name (bytes) Linux file systems accept (ext4, xfs, btrfs, tmpfs: `NAME_MAX`).
pub const NAME_MAX: usize = 255;

/// Bytes a temporary name adds to a final one: `.` before it, then `.`, a process id of up to
/// 10 digits (any `u32`) and `.tmp` after it.
const TMP_EXTRA: usize = 1 + 1 + 10 + 4;

/// The longest final name: its temporary name still fits in [`NAME_MAX`].
pub const FINAL_MAX: usize = NAME_MAX - TMP_EXTRA;

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

    /// The file name of the item at manifest position `index` with id `id`, ending in
    /// `extension` (without the dot): `{index}-{stem}.{extension}`, at most [`FINAL_MAX`] bytes.
    pub fn file_name(&self, index: u64, id: &str, extension: &str) -> String {
        let prefix = format!("{index:0width$}-", width = self.width);
        let room = FINAL_MAX.saturating_sub(prefix.len() + 1 + extension.len());
        let mut stem = readable_stem(id);
        // The stem is ASCII, so any byte count is a character boundary.
        stem.truncate(room);
        format!("{prefix}{stem}.{extension}")
    }
}

/// The temporary name a file is written under before its rename, unique per process:
/// `.NAME.PID.tmp` (hidden, so a glob for `*.npz` never sees half a file).
pub fn tmp_name(final_name: &str) -> String {
    tmp_name_of(final_name, std::process::id())
}

/// [`tmp_name`] for the process `pid`.
fn tmp_name_of(final_name: &str, pid: u32) -> String {
    format!(".{final_name}.{pid}.tmp")
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
    fn ids_that_share_a_stem_get_names_of_their_own() {
        let names = ExportNames::for_job(5);
        let ids = [
            "chair/1", "chair 1", "chair_1", "椅子", "桌子", "Chair_1", "CHAIR_1",
        ];
        let files: Vec<String> = ids
            .iter()
            .enumerate()
            .map(|(i, id)| names.file_name(i as u64, id, "npz"))
            .collect();
        assert_eq!(files[0], "000000-chair_1.npz");
        assert_eq!(files[3], "000003-__.npz");
        // Unique even where the file system ignores case.
        let folded: BTreeSet<String> = files.iter().map(|f| f.to_lowercase()).collect();
        assert_eq!(folded.len(), ids.len());
    }

    #[test]
    fn every_name_and_its_temporary_name_fit_for_any_id_length() {
        let names = ExportNames::for_job(20_000_000);
        for len in (0..300).chain([1000, 100_000]) {
            for unit in ["a", "é", "椅", "/"] {
                let id = unit.repeat(len);
                let name = names.file_name(12_345_678, &id, "npz");
                assert!(name.len() <= FINAL_MAX, "{len} × {unit}: {}", name.len());
                let tmp = tmp_name_of(&name, u32::MAX);
                assert!(tmp.len() <= NAME_MAX, "{len} × {unit}: {}", tmp.len());
                assert!(
                    name.starts_with("12345678-") && name.ends_with(".npz"),
                    "{name}"
                );
            }
        }
        // Two long ids that differ only past the cut still differ by index.
        let a = names.file_name(1, &"x".repeat(400), "npz");
        let b = names.file_name(2, &"x".repeat(401), "npz");
        assert_ne!(a, b);
    }

    #[test]
    fn names_sort_in_manifest_order() {
        let small = ExportNames::for_job(3);
        assert!(small.file_name(9, "b", "npz") < small.file_name(10, "a", "npz"));
        let big = ExportNames::for_job(12_000_000);
        assert_eq!(big.file_name(7, "a", "npz"), "00000007-a.npz");
        assert!(big.file_name(999_999, "z", "npz") < big.file_name(10_000_000, "a", "npz"));
    }
}
