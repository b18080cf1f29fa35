//! An 8-bit RGB raster with clipped drawing primitives and PNG encoding.

use std::path::Path;

use crate::error::{Result, VizError};

/// The largest width or height [`RgbImage::new`] accepts, in pixels.
pub const MAX_DIMENSION: usize = 16_384;

/// An sRGB colour, 8 bits per channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Rgb(pub [u8; 3]);

impl Rgb {
    /// Black.
    pub const BLACK: Rgb = Rgb([0, 0, 0]);
    /// White.
    pub const WHITE: Rgb = Rgb([255, 255, 255]);
    /// A mid grey for secondary lines and text.
    pub const GREY: Rgb = Rgb([128, 128, 128]);
    /// A red for markers.
    pub const RED: Rgb = Rgb([220, 40, 40]);
    /// A blue for line plots.
    pub const BLUE: Rgb = Rgb([31, 96, 180]);

    /// A colour from its three channels.
    pub const fn new(r: u8, g: u8, b: u8) -> Self {
        Rgb([r, g, b])
    }

    /// Linear blend: `self` at `t = 0`, `other` at `t = 1` (`t` is clamped; NaN counts as 0).
    pub fn lerp(self, other: Rgb, t: f32) -> Rgb {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let mix = |a: u8, b: u8| (f32::from(a) + (f32::from(b) - f32::from(a)) * t).round() as u8;
        Rgb([mix(self.0[0], other.0[0]), mix(self.0[1], other.0[1]), mix(self.0[2], other.0[2])])
    }
}

/// An 8-bit RGB image, rows top to bottom, pixels left to right.
///
/// Every drawing method takes signed coordinates and silently clips what falls outside, so drawing never
/// panics.
///
/// # Example
/// ```
/// use nlos_viz::{Rgb, RgbImage};
/// let mut img = RgbImage::new(4, 3, Rgb::WHITE)?;
/// img.fill_rect(-1, -1, 2, 2, Rgb::BLACK); // clipped to the pixel (0, 0)
/// assert_eq!(img.get(0, 0), Some(Rgb::BLACK));
/// assert_eq!(img.get(1, 1), Some(Rgb::WHITE));
/// let png = img.encode_png()?;
/// assert!(png.starts_with(b"\x89PNG"));
/// # Ok::<(), nlos_viz::VizError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

impl RgbImage {
    /// An image filled with `fill`.
    ///
    /// # Errors
    /// [`VizError::InvalidSize`] when a side is zero or exceeds [`MAX_DIMENSION`].
    pub fn new(width: usize, height: usize, fill: Rgb) -> Result<Self> {
        if width == 0 || height == 0 || width > MAX_DIMENSION || height > MAX_DIMENSION {
            return Err(VizError::InvalidSize {
                width,
                height,
                reason: format!("each side must be in 1..={MAX_DIMENSION} pixels"),
            });
        }
        let data = fill.0.iter().copied().cycle().take(width * height * 3).collect();
        Ok(Self { width, height, data })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The raw bytes, `R G B` per pixel, row-major from the top.
    pub fn as_raw(&self) -> &[u8] {
        &self.data
    }

    /// The pixel at `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<Rgb> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y * self.width + x) * 3;
        Some(Rgb([self.data[i], self.data[i + 1], self.data[i + 2]]))
    }

    /// Sets the pixel at `(x, y)`; does nothing outside the image.
    pub fn set(&mut self, x: i64, y: i64, c: Rgb) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let i = (y as usize * self.width + x as usize) * 3;
        self.data[i..i + 3].copy_from_slice(&c.0);
    }

    /// Fills the rectangle with top-left `(x, y)` and size `w × h` (clipped; empty when `w` or `h` ≤ 0).
    pub fn fill_rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        let x0 = x.clamp(0, self.width as i64);
        let y0 = y.clamp(0, self.height as i64);
        let x1 = x.saturating_add(w).clamp(0, self.width as i64);
        let y1 = y.saturating_add(h).clamp(0, self.height as i64);
        for yy in y0..y1 {
            for xx in x0..x1 {
                let i = (yy as usize * self.width + xx as usize) * 3;
                self.data[i..i + 3].copy_from_slice(&c.0);
            }
        }
    }

    /// The outline of a `w × h` rectangle, one pixel wide, inside the rectangle.
    pub fn rect_outline(&mut self, x: i64, y: i64, w: i64, h: i64, c: Rgb) {
        if w <= 0 || h <= 0 {
            return;
        }
        self.fill_rect(x, y, w, 1, c);
        self.fill_rect(x, y + h - 1, w, 1, c);
        self.fill_rect(x, y, 1, h, c);
        self.fill_rect(x + w - 1, y, 1, h, c);
    }

    /// A straight line from `(x0, y0)` to `(x1, y1)`, both ends included (Bresenham).
    pub fn line(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, c: Rgb) {
        // Keep far-away endpoints from looping for ages: clamp to a margin around the image.
        let lim = |v: i64, n: usize| v.clamp(-(n as i64) - 1, 2 * n as i64 + 1);
        let (mut x, mut y) = (lim(x0, self.width), lim(y0, self.height));
        let (x1, y1) = (lim(x1, self.width), lim(y1, self.height));
        let dx = (x1 - x).abs();
        let dy = -(y1 - y).abs();
        let sx = if x < x1 { 1 } else { -1 };
        let sy = if y < y1 { 1 } else { -1 };
        let mut err = dx + dy;
        loop {
            self.set(x, y, c);
            if x == x1 && y == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// Copies `src` with its top-left corner at `(x, y)` (clipped).
    pub fn blit(&mut self, src: &RgbImage, x: i64, y: i64) {
        for sy in 0..src.height {
            for sx in 0..src.width {
                if let Some(c) = src.get(sx, sy) {
                    self.set(x + sx as i64, y + sy as i64, c);
                }
            }
        }
    }

    /// Encodes the image as an 8-bit RGB PNG.
    ///
    /// # Errors
    /// [`VizError::Png`] when the encoder fails.
    pub fn encode_png(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        {
            // Sizes are bounded by MAX_DIMENSION, so the casts are lossless.
            let mut enc = png::Encoder::new(&mut out, self.width as u32, self.height as u32);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut writer = enc.write_header()?;
            writer.write_image_data(&self.data)?;
            writer.finish()?;
        }
        Ok(out)
    }

    /// Encodes the image as PNG and writes it to `path`.
    ///
    /// # Errors
    /// [`VizError::Png`]; [`VizError::Io`] naming the file.
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        let bytes = self.encode_png()?;
        std::fs::write(path, bytes).map_err(|source| VizError::Io { file: path.into(), source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_sizes() {
        assert!(RgbImage::new(0, 5, Rgb::WHITE).is_err());
        assert!(RgbImage::new(5, MAX_DIMENSION + 1, Rgb::WHITE).is_err());
    }

    #[test]
    fn drawing_clips() {
        let mut img = RgbImage::new(5, 5, Rgb::WHITE).expect("image");
        img.fill_rect(3, 3, 100, 100, Rgb::BLACK);
        img.line(-1000, 2, 1000, 2, Rgb::RED);
        img.set(-1, 9, Rgb::BLACK);
        assert_eq!(img.get(4, 4), Some(Rgb::BLACK));
        assert_eq!(img.get(2, 3), Some(Rgb::WHITE));
        assert!((0..5).all(|x| img.get(x, 2) == Some(Rgb::RED)));
        assert_eq!(img.get(5, 0), None);
    }

    #[test]
    fn png_round_trip() {
        let mut img = RgbImage::new(7, 3, Rgb::WHITE).expect("image");
        img.set(6, 2, Rgb::new(1, 2, 3));
        let bytes = img.encode_png().expect("encode");
        let dec = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = dec.read_info().expect("header");
        let mut buf = vec![0; reader.output_buffer_size().expect("size")];
        let info = reader.next_frame(&mut buf).expect("frame");
        assert_eq!((info.width, info.height), (7, 3));
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(&buf[..info.buffer_size()], img.as_raw());
    }
}
