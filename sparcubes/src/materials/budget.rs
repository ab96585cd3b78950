//! How many texture pixels one item may decode (issue 64 item 4: nothing bounded an item's
//! textures but the 8192² cap on each image, so an OBJ naming forty distinct 8192² maps could
//! ask for 13 GiB of decoded texels and mip levels, past the worker's default memory limit).
//!
//! The budget is a quarter of the item's memory limit (`--item-memory`,
//! `limits.item_memory_bytes`): a decoded texel is 4 bytes (8-bit RGBA) and its mip levels a
//! third again (`attributes/mips.rs`), so `bytes × 3 / 64` pixels. At the default 8 GiB that is
//! 402,653,184 pixels, six 8192² images or twenty-four 4096² ones. Images are decoded in the
//! order the file names them; one that would take the budget past its end is not decoded and
//! is named in the facts (`appearance_not_read`) with what was left, and the item keeps its
//! shape and every image decoded before.

use super::image::{self, Image};

/// The item memory limit [`TextureBudget::default`] assumes: the job's default
/// (`limits.item_memory_bytes`, 8 GiB).
const DEFAULT_ITEM_MEMORY: u64 = 8 << 30;

/// Texture pixels an item may still decode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TextureBudget {
    left: u64,
}

impl TextureBudget {
    /// The budget of an item whose memory is limited to `bytes` (0: no limit, no budget).
    pub fn within_item_memory(bytes: u64) -> Self {
        let left = match bytes {
            0 => u64::MAX,
            b => b.saturating_mul(3) / 64,
        };
        TextureBudget { left }
    }

    /// Pixels still to be decoded.
    pub fn left(&self) -> u64 {
        self.left
    }

    /// Decodes `bytes` if its image fits in what is left (and under [`image::MAX_PIXELS`]), taking
    /// its pixels from the budget; the error says why not.
    pub(crate) fn decode(&mut self, bytes: &[u8]) -> Result<Image, String> {
        let decoded = image::decode_within(bytes, self.left)?;
        self.left -= decoded.width as u64 * decoded.height as u64;
        Ok(decoded)
    }
}

impl Default for TextureBudget {
    /// The budget under the default item memory limit.
    fn default() -> Self {
        TextureBudget::within_item_memory(DEFAULT_ITEM_MEMORY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(side: u32) -> Vec<u8> {
        image::tests::png_bytes(side, side, |_, _| [200, 10, 10, 255])
    }

    #[test]
    fn images_past_the_budget_are_refused_saying_what_was_left() {
        // 64 KiB of item memory: 3072 pixels, three 32² images.
        let mut budget = TextureBudget::within_item_memory(64 << 10);
        assert_eq!(budget.left(), 3072);
        for _ in 0..3 {
            assert!(budget.decode(&solid(32)).is_ok());
        }
        assert_eq!(budget.left(), 0);
        let err = budget.decode(&solid(32)).expect_err("over the budget");
        assert!(
            err.contains("32×32") && err.contains("0 pixels left"),
            "{err}"
        );
        let err = budget.decode(&solid(1)).expect_err("nothing left");
        assert!(err.contains("texture budget"), "{err}");
    }

    #[test]
    fn the_default_is_six_of_the_largest_images_and_no_limit_is_no_budget() {
        assert_eq!(TextureBudget::default().left(), 6 * image::MAX_PIXELS);
        assert_eq!(TextureBudget::within_item_memory(0).left(), u64::MAX);
    }
}
