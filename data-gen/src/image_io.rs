//! The RGBA float image of the project and its PNG output.

use std::path::Path;

use crate::error::DataGenError;

/// Linear RGB → sRGB transfer (IEC 61966-2-1), for `c ∈ [0, 1]`.
#[inline]
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB → linear RGB transfer, for `c ∈ [0, 1]`.
#[inline]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// A linear-RGB image with **premultiplied** alpha, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct RgbaImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width × height` pixels `[r·a, g·a, b·a, a]`.
    pub pixels: Vec<[f32; 4]>,
}

impl RgbaImage {
    /// A transparent black image.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            pixels: vec![[0.0; 4]; width * height],
        }
    }

    /// Pixel `(i, j)`.
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> [f32; 4] {
        self.pixels[j * self.width + i]
    }

    /// The image as 8-bit codes, four per pixel (sRGB colour, straight (un-premultiplied)
    /// alpha), row-major: what [`Self::write_png`] stores.
    pub fn srgb8_codes(&self) -> Vec<u8> {
        let mut codes = Vec::with_capacity(self.pixels.len() * 4);
        for p in &self.pixels {
            let a = p[3].clamp(0.0, 1.0);
            let q = |c: f32| {
                let straight = if a > 0.0 { c / a } else { 0.0 };
                (linear_to_srgb(straight.clamp(0.0, 1.0)) * 255.0).round() as u8
            };
            codes.extend([q(p[0]), q(p[1]), q(p[2]), (a * 255.0).round() as u8]);
        }
        codes
    }

    /// Writes the image as an 8-bit sRGB PNG with straight (un-premultiplied) alpha.
    pub fn write_png(&self, path: &Path) -> Result<(), DataGenError> {
        let (w, h) = (self.width as u32, self.height as u32);
        let buf = image::RgbaImage::from_raw(w, h, self.srgb8_codes())
            .expect("four codes per pixel of a width × height image");
        write_image(path, &image::DynamicImage::ImageRgba8(buf))
    }

    /// The image composited over an opaque background colour (linear RGB), alpha set to 1.
    pub fn over(&self, background: [f32; 3]) -> RgbaImage {
        let pixels = self
            .pixels
            .iter()
            .map(|p| {
                let t = 1.0 - p[3];
                [
                    p[0] + t * background[0],
                    p[1] + t * background[1],
                    p[2] + t * background[2],
                    1.0,
                ]
            })
            .collect();
        RgbaImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Places images side by side (tops aligned, transparent padding) for reports.
    pub fn side_by_side(images: &[&RgbaImage]) -> RgbaImage {
        let width = images.iter().map(|i| i.width).sum();
        let height = images.iter().map(|i| i.height).max().unwrap_or(0);
        let mut out = RgbaImage::new(width, height);
        let mut x0 = 0;
        for img in images {
            for j in 0..img.height {
                for i in 0..img.width {
                    out.pixels[j * width + x0 + i] = img.get(i, j);
                }
            }
            x0 += img.width;
        }
        out
    }
}

/// Writes any `image` buffer, creating parent folders, mapping errors to [`DataGenError`].
pub(crate) fn write_image(path: &Path, img: &image::DynamicImage) -> Result<(), DataGenError> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| DataGenError::Io {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    img.save(path).map_err(|e| DataGenError::ImageWrite {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}
