//! Text labels burnt into preview pictures ("SOURCE", "OUTPUT"), drawn with a built-in 5×7
//! pixel font of the few capital letters they need, white on a dark box.

use crate::Image;

/// Letter colour.
const INK: [u8; 3] = [255, 255, 255];
/// Colour of the box behind the letters.
const BOX: [u8; 3] = [40, 40, 40];
/// Pixels of margin inside the box, before scaling.
const PAD: u32 = 2;

/// The 5×7 glyph of `c` (one byte per row, bit 4 the leftmost pixel); blank for letters the
/// labels do not use.
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        'C' => [0x0f, 0x10, 0x10, 0x10, 0x10, 0x10, 0x0f],
        'E' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f],
        'O' => [0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'P' => [0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10],
        'R' => [0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11],
        'S' => [0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e],
        'T' => [0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        _ => [0; 7],
    }
}

/// Draws `text` in a dark box whose top-left corner is (`x`, `y`), each font pixel `scale`
/// pixels wide; what falls outside the picture is clipped.
pub fn draw(image: &mut Image, x: u32, y: u32, text: &str, scale: u32) {
    let s = scale.max(1);
    let letters = text.chars().count() as u32;
    let width = (letters * 6 - 1 + 2 * PAD) * s;
    image.fill_rect(x, y, x + width, y + (7 + 2 * PAD) * s, BOX);
    for (i, c) in (0..).zip(text.chars()) {
        let left = x + (PAD + 6 * i) * s;
        for (row, bits) in (0..).zip(glyph(c)) {
            for col in 0..5 {
                if bits & (0x10 >> col) != 0 {
                    let (px, py) = (left + col * s, y + (PAD + row) * s);
                    image.fill_rect(px, py, px + s, py + s, INK);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letters_are_drawn_where_the_glyph_says() {
        let mut image = Image::filled(100, 40, [0, 0, 0]);
        draw(&mut image, 10, 5, "SO", 2);
        let at = |x: u32, y: u32| image.pixel(x, y);
        // 'S' row 0 is .XXXX: its first pixel is box, its second ink.
        let (x0, y0) = (10 + PAD * 2, 5 + PAD * 2);
        assert_eq!(at(x0, y0), Some(BOX));
        assert_eq!(at(x0 + 2, y0), Some(INK));
        // 'O' (second letter) row 1 is X...X.
        let x1 = x0 + 12;
        assert_eq!(at(x1, y0 + 2), Some(INK));
        assert_eq!(at(x1 + 2, y0 + 2), Some(BOX));
        assert_eq!(at(x1 + 8, y0 + 2), Some(INK));
        // Outside the box nothing changed; a label past the edge is clipped, not a panic.
        assert_eq!(at(9, 5), Some([0, 0, 0]));
        draw(&mut image, 95, 35, "OUTPUT?", 3);
    }
}
