//! A small embedded bitmap font: 5 × 7 pixel glyphs (plus one descender row) in a 6 × 10 cell.
//!
//! Covers digits, ASCII letters, space and `. , ; - + ( ) / : = _ % [ ] < > ' | * # ? ! "` plus `×` and
//! `µ`; any other character draws as a hollow box. Text is drawn at an integer `scale` (each font pixel
//! becomes a `scale × scale` block).

use crate::image::{Rgb, RgbImage};

/// Width of a glyph in font pixels.
pub const GLYPH_WIDTH: usize = 5;
/// Height of a glyph above the baseline in font pixels (capitals and digits fill it).
pub const GLYPH_HEIGHT: usize = 7;
/// Horizontal advance from one character to the next, in font pixels.
pub const ADVANCE: usize = 6;
/// Height of a line of text including the descender row, in font pixels.
pub const TEXT_HEIGHT: usize = 8;

/// The rows of glyph `c`, top to bottom; bit 4 is the leftmost column. Row 7 is the descender.
pub fn glyph(c: char) -> [u8; 8] {
    let g: [u8; 8] = match c {
        ' ' => [0, 0, 0, 0, 0, 0, 0, 0],
        '0' => [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110, 0],
        '1' => [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110, 0],
        '2' => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111, 0],
        '3' => [0b11111, 0b00010, 0b00100, 0b00010, 0b00001, 0b10001, 0b01110, 0],
        '4' => [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010, 0],
        '5' => [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110, 0],
        '6' => [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110, 0],
        '7' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0],
        '8' => [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110, 0],
        '9' => [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100, 0],
        'A' => [0b01110, 0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0],
        'B' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110, 0],
        'C' => [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110, 0],
        'D' => [0b11100, 0b10010, 0b10001, 0b10001, 0b10001, 0b10010, 0b11100, 0],
        'E' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111, 0],
        'F' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000, 0],
        'G' => [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111, 0],
        'H' => [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001, 0],
        'I' => [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110, 0],
        'J' => [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100, 0],
        'K' => [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001, 0],
        'L' => [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111, 0],
        'M' => [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001, 0],
        'N' => [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001, 0],
        'O' => [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110, 0],
        'P' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000, 0],
        'Q' => [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101, 0],
        'R' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001, 0],
        'S' => [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110, 0],
        'T' => [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0],
        'U' => [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110, 0],
        'V' => [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0],
        'W' => [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010, 0],
        'X' => [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001, 0],
        'Y' => [0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100, 0],
        'Z' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111, 0],
        'a' => [0, 0, 0b01110, 0b00001, 0b01111, 0b10001, 0b01111, 0],
        'b' => [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b11110, 0],
        'c' => [0, 0, 0b01110, 0b10000, 0b10000, 0b10001, 0b01110, 0],
        'd' => [0b00001, 0b00001, 0b01101, 0b10011, 0b10001, 0b10001, 0b01111, 0],
        'e' => [0, 0, 0b01110, 0b10001, 0b11111, 0b10000, 0b01110, 0],
        'f' => [0b00110, 0b01001, 0b01000, 0b11100, 0b01000, 0b01000, 0b01000, 0],
        'g' => [0, 0, 0b01111, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110],
        'h' => [0b10000, 0b10000, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001, 0],
        'i' => [0b00100, 0, 0b01100, 0b00100, 0b00100, 0b00100, 0b01110, 0],
        'j' => [0b00010, 0, 0b00110, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100],
        'k' => [0b10000, 0b10000, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0],
        'l' => [0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110, 0],
        'm' => [0, 0, 0b11010, 0b10101, 0b10101, 0b10001, 0b10001, 0],
        'n' => [0, 0, 0b10110, 0b11001, 0b10001, 0b10001, 0b10001, 0],
        'o' => [0, 0, 0b01110, 0b10001, 0b10001, 0b10001, 0b01110, 0],
        'p' => [0, 0, 0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000],
        'q' => [0, 0, 0b01111, 0b10001, 0b10001, 0b01111, 0b00001, 0b00001],
        'r' => [0, 0, 0b10110, 0b11001, 0b10000, 0b10000, 0b10000, 0],
        's' => [0, 0, 0b01111, 0b10000, 0b01110, 0b00001, 0b11110, 0],
        't' => [0b01000, 0b01000, 0b11100, 0b01000, 0b01000, 0b01001, 0b00110, 0],
        'u' => [0, 0, 0b10001, 0b10001, 0b10001, 0b10011, 0b01101, 0],
        'v' => [0, 0, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100, 0],
        'w' => [0, 0, 0b10001, 0b10001, 0b10101, 0b10101, 0b01010, 0],
        'x' => [0, 0, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0],
        'y' => [0, 0, 0b10001, 0b10001, 0b10001, 0b01111, 0b00001, 0b01110],
        'z' => [0, 0, 0b11111, 0b00010, 0b00100, 0b01000, 0b11111, 0],
        '.' => [0, 0, 0, 0, 0, 0b01100, 0b01100, 0],
        ',' => [0, 0, 0, 0, 0, 0b01100, 0b00100, 0b01000],
        ';' => [0, 0b01100, 0b01100, 0, 0, 0b01100, 0b00100, 0b01000],
        '-' | '–' | '−' => [0, 0, 0, 0b01110, 0, 0, 0, 0],
        '+' => [0, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0, 0],
        '(' => [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010, 0],
        ')' => [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000, 0],
        '/' => [0, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0, 0],
        ':' => [0, 0b01100, 0b01100, 0, 0b01100, 0b01100, 0, 0],
        '=' => [0, 0, 0b11111, 0, 0b11111, 0, 0, 0],
        '_' => [0, 0, 0, 0, 0, 0, 0b11111, 0],
        '%' => [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011, 0],
        '[' => [0b01110, 0b01000, 0b01000, 0b01000, 0b01000, 0b01000, 0b01110, 0],
        ']' => [0b01110, 0b00010, 0b00010, 0b00010, 0b00010, 0b00010, 0b01110, 0],
        '<' => [0b00010, 0b00100, 0b01000, 0b10000, 0b01000, 0b00100, 0b00010, 0],
        '>' => [0b01000, 0b00100, 0b00010, 0b00001, 0b00010, 0b00100, 0b01000, 0],
        '\'' => [0b01100, 0b00100, 0b01000, 0, 0, 0, 0, 0],
        '"' => [0b01010, 0b01010, 0b01010, 0, 0, 0, 0, 0],
        '|' => [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0],
        '*' => [0, 0b00100, 0b10101, 0b01110, 0b10101, 0b00100, 0, 0],
        '#' => [0b01010, 0b01010, 0b11111, 0b01010, 0b11111, 0b01010, 0b01010, 0],
        '?' => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0, 0b00100, 0],
        '!' => [0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0, 0b00100, 0],
        '×' => [0, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0, 0],
        'µ' | 'μ' => [0, 0, 0b10001, 0b10001, 0b10011, 0b11101, 0b10000, 0b10000],
        _ => [0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111, 0],
    };
    g
}

/// Width in pixels of `text` drawn at `scale` (no trailing gap; 0 for empty text).
pub fn text_width(text: &str, scale: usize) -> usize {
    let n = text.chars().count();
    if n == 0 { 0 } else { (n * ADVANCE - 1) * scale }
}

/// Height in pixels of one line of text at `scale`, descender included.
pub fn text_height(scale: usize) -> usize {
    TEXT_HEIGHT * scale
}

/// Draws `text` left to right with the top-left corner of its first glyph at `(x, y)`; clipped.
/// A `scale` of 0 draws nothing.
///
/// # Example
/// ```
/// use nlos_viz::{draw_text, Rgb, RgbImage};
/// let mut img = RgbImage::new(20, 10, Rgb::WHITE)?;
/// draw_text(&mut img, 1, 1, "-", Rgb::BLACK, 1);
/// // '-' is the middle three columns of glyph row 3.
/// assert_eq!(img.get(2, 4), Some(Rgb::BLACK));
/// assert_eq!(img.get(1, 4), Some(Rgb::WHITE));
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
pub fn draw_text(img: &mut RgbImage, x: i64, y: i64, text: &str, color: Rgb, scale: usize) {
    let s = scale as i64;
    for (i, c) in text.chars().enumerate() {
        let gx = x + (i * ADVANCE) as i64 * s;
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..GLYPH_WIDTH {
                if bits & (1 << (GLYPH_WIDTH - 1 - col)) != 0 {
                    img.fill_rect(gx + col as i64 * s, y + row as i64 * s, s, s, color);
                }
            }
        }
    }
}

/// Draws `text` rotated a quarter turn anticlockwise (reading bottom to top), for vertical axis titles.
/// `(x, y)` is the top-left corner of the rotated text's bounding box, which is
/// [`text_height`] wide and [`text_width`] tall.
pub fn draw_text_vertical(img: &mut RgbImage, x: i64, y: i64, text: &str, color: Rgb, scale: usize) {
    let s = scale as i64;
    let len = text_width(text, scale) as i64;
    for (i, c) in text.chars().enumerate() {
        // Unrotated position (u, v) of a font pixel maps to (x + v, y + len − 1 − u).
        let gu = (i * ADVANCE) as i64 * s;
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..GLYPH_WIDTH {
                if bits & (1 << (GLYPH_WIDTH - 1 - col)) != 0 {
                    let u = gu + col as i64 * s;
                    let v = row as i64 * s;
                    img.fill_rect(x + v, y + len - u - s, s, s, color);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dark(img: &RgbImage) -> Vec<(usize, usize)> {
        let mut v = Vec::new();
        for y in 0..img.height() {
            for x in 0..img.width() {
                if img.get(x, y) == Some(Rgb::BLACK) {
                    v.push((x, y));
                }
            }
        }
        v
    }

    #[test]
    fn text_pixels_land_where_expected() {
        let mut img = RgbImage::new(30, 20, Rgb::WHITE).expect("image");
        draw_text(&mut img, 3, 2, "1", Rgb::BLACK, 1);
        let mut expected = vec![(5, 2), (4, 3), (5, 3), (4, 8), (5, 8), (6, 8)];
        expected.extend((4..8).map(|y| (5, y)));
        expected.sort_by_key(|&(x, y)| (y, x));
        assert_eq!(dark(&img), expected);
    }

    #[test]
    fn scaled_text_and_advance() {
        let mut img = RgbImage::new(40, 20, Rgb::WHITE).expect("image");
        draw_text(&mut img, 0, 0, ".:", Rgb::BLACK, 2);
        // '.' occupies columns 1..3 of rows 5..7 → pixels 2..6 × 10..14 at scale 2.
        assert_eq!(img.get(2, 10), Some(Rgb::BLACK));
        assert_eq!(img.get(5, 13), Some(Rgb::BLACK));
        assert_eq!(img.get(6, 13), Some(Rgb::WHITE));
        // ':' starts one advance (12 px) later; its top dot is at rows 1..3 → y 2..6.
        assert_eq!(img.get(14, 2), Some(Rgb::BLACK));
        assert_eq!(img.get(14, 0), Some(Rgb::WHITE));
        assert_eq!(text_width(".:", 2), 22);
        assert_eq!(text_width("", 3), 0);
    }

    #[test]
    fn vertical_text_is_rotated() {
        let mut img = RgbImage::new(20, 20, Rgb::WHITE).expect("image");
        draw_text_vertical(&mut img, 0, 0, "-", Rgb::BLACK, 1);
        // Horizontal '-' (row 3, columns 1..4) becomes a vertical bar at x = 3, y = 1..4.
        assert_eq!(dark(&img), vec![(3, 1), (3, 2), (3, 3)]);
    }

    #[test]
    fn every_listed_character_has_a_glyph_and_unknown_is_a_box() {
        let boxed = glyph('\u{2603}');
        for c in "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz.-+()/: ,;=_%[]<>'|*#?!\"×µ".chars() {
            assert!(glyph(c) != boxed, "{c}");
            assert!(glyph(c).iter().all(|&r| r < 32), "{c}");
        }
        assert_eq!(glyph(' '), [0; 8]);
    }

    #[test]
    fn drawing_off_image_does_not_panic() {
        let mut img = RgbImage::new(3, 3, Rgb::WHITE).expect("image");
        draw_text(&mut img, -100, 1000, "abc", Rgb::BLACK, 5);
        draw_text_vertical(&mut img, i64::MAX / 4, -5, "xyz", Rgb::BLACK, 2);
        draw_text(&mut img, 0, 0, "1", Rgb::BLACK, 0);
    }
}
