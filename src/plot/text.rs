//! Labels for the pictures: a 5 × 7 pixel font of the characters the axes
//! need (digits, sign, point, degree, `m`, `c`), and the 8 × 8 bitmap font
//! of the `font8x8` crate for the rest of ASCII (titles, legends), drawn at
//! any integer scale, so that no font file or font library is needed.

use image::{Rgb, RgbImage};

/// Glyph width of the axes' own font, and the line height (the taller
/// 8 × 8 font's), in font pixels; one blank column between glyphs.
const GLYPH_W: u32 = 5;
const GLYPH_H: u32 = 8;

/// A character's pixels: width, and each row's bits (bit `width − 1 − x`
/// for column `x`), top first.
fn pixels(c: char) -> Option<(u32, [u8; 8])> {
    // Letters all from one font, the 8 × 8 one; digits and signs compact.
    if let Some(rows) = glyph(c).filter(|_| !c.is_ascii_alphabetic()) {
        let mut out = [0u8; 8];
        out[..7].copy_from_slice(&rows);
        return Some((GLYPH_W, out));
    }
    use font8x8::UnicodeFonts;
    // font8x8 keeps column x in bit x: mirrored into this file's order.
    font8x8::BASIC_FONTS
        .get(c)
        .map(|rows| (8, rows.map(|r| r.reverse_bits())))
}
/// A glyph's rows, top first; bit 4 is the leftmost pixel.
fn glyph(c: char) -> Option<[u8; 7]> {
    Some(match c {
        '0' => [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110],
        '1' => [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        '2' => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111],
        '3' => [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110],
        '4' => [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010],
        '5' => [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110],
        '6' => [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110],
        '7' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000],
        '8' => [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110],
        '9' => [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100],
        '.' => [0, 0, 0, 0, 0, 0b01100, 0b01100],
        '-' => [0, 0, 0, 0b11111, 0, 0, 0],
        '+' => [0, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0],
        'm' => [0, 0, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001],
        'c' => [0, 0, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110],
        '°' => [0b01100, 0b10010, 0b10010, 0b01100, 0, 0, 0],
        ' ' => [0; 7],
        _ => return None,
    })
}

/// Width of `text` in image pixels at `scale` (characters without a glyph
/// take no room).
pub fn text_width(text: &str, scale: u32) -> u32 {
    let w: u32 = text.chars().filter_map(pixels).map(|(w, _)| w + 1).sum();
    w.saturating_sub(1) * scale
}

/// Height of a line of text in image pixels at `scale`.
pub fn text_height(scale: u32) -> u32 {
    GLYPH_H * scale
}

/// Draws `text` with its top left corner at `(x, y)`, each font pixel a
/// `scale`-pixel square; pixels outside the image are left out.
pub fn draw_text(img: &mut RgbImage, x: i32, y: i32, text: &str, colour: Rgb<u8>, scale: u32) {
    let s = scale as i32;
    let mut left = x;
    for (width, rows) in text.chars().filter_map(pixels) {
        for (r, bits) in rows.iter().enumerate() {
            for col in 0..width as i32 {
                if bits >> (width as i32 - 1 - col) & 1 == 0 {
                    continue;
                }
                for dy in 0..s {
                    for dx in 0..s {
                        let (px, py) = (left + col * s + dx, y + r as i32 * s + dy);
                        if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                            img.put_pixel(px as u32, py as u32, colour);
                        }
                    }
                }
            }
        }
        left += (width as i32 + 1) * s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_drawn_inside_its_box_and_clipped_at_the_edges() {
        let white = Rgb([255, 255, 255]);
        let ink = Rgb([0, 0, 0]);
        let mut img = RgbImage::from_pixel(40, 20, white);
        draw_text(&mut img, 2, 3, "1.5m", ink, 1);
        let (w, h) = (text_width("1.5m", 1), text_height(1));
        assert_eq!((w, h), (26, 8));
        for (x, y, p) in img.enumerate_pixels() {
            let inside = (2..2 + w).contains(&x) && (3..3 + h).contains(&y);
            assert!(inside || *p == white, "ink outside the box at ({x}, {y})");
        }
        // The "1": its stem is the glyph's middle column, rows 0-6.
        assert!((3..10).all(|y| *img.get_pixel(4, y) == ink));
        // Doubled, and partly off the image: no panic, ink only inside.
        draw_text(&mut img, 30, 15, "88", ink, 2);
        assert_eq!(*img.get_pixel(30, 15), white, "the 8's top left is blank");
        assert_eq!(*img.get_pixel(32, 15), ink);
        // Other ASCII comes from the 8 × 8 font; the rest takes no room.
        assert_eq!(text_width("a1", 1), 8 + 1 + 5);
        assert_eq!(text_width("→1", 1), text_width("1", 1));
        let mut a = RgbImage::from_pixel(10, 10, white);
        draw_text(&mut a, 0, 0, "I", ink, 1);
        assert!(a.pixels().filter(|p| **p == ink).count() > 6, "an I is drawn");
    }
}
