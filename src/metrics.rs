//! Image metrics against the ground truth: RMSE, PSNR, max error, share of pixels above a
//! threshold, all with masks for undefined pixels; silhouette IoU; the error split by distance to
//! the true silhouette.
//!
//! Images are [`RgbaImage`]s: linear RGB with premultiplied alpha, values nominally in `[0, 1]`.
//! Errors are computed over the four premultiplied channels, so a silhouette error counts like a
//! colour error. PSNR uses a peak of 1: `PSNR = 10·log10(1 / MSE)` dB; identical images give
//! `f64::INFINITY`.
//!
//! **Nothing visible is not a perfect score.** Two pictures that are both empty (every compared
//! pixel zero in all four channels, or no silhouette pixel in either) agree trivially; [`compare`]
//! and [`silhouette_iou`] return [`MetricsError::NothingVisible`] for them instead of an infinite
//! PSNR or an IoU of 1, so that an object no view sees cannot be reported as perfectly
//! reproduced.

use altrep_data_gen::RgbaImage;
use serde::Serialize;

/// What went wrong in a comparison.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MetricsError {
    /// The two images differ in size.
    #[error("image sizes differ: {a:?} vs {b:?}")]
    SizeMismatch {
        /// Width and height of the first image.
        a: (usize, usize),
        /// Width and height of the second image.
        b: (usize, usize),
    },
    /// The mask does not have one entry per pixel.
    #[error("mask has {mask} entries for {pixels} pixels")]
    MaskSize {
        /// Entries in the mask.
        mask: usize,
        /// Pixels in the images.
        pixels: usize,
    },
    /// No pixel is left to compare (empty image or empty mask).
    #[error("no pixel to compare (empty image or all-false mask)")]
    NothingToCompare,
    /// Both pictures are empty (nothing visible in the reference nor in the result): agreement
    /// is trivial and no error figure is meaningful.
    #[error(
        "nothing visible: the reference and the compared picture are both empty, so no error can be measured"
    )]
    NothingVisible,
    /// A pixel holds NaN or infinity.
    #[error("pixel {index} of the {which} image is not finite")]
    NonFinite {
        /// `"first"` or `"second"`.
        which: &'static str,
        /// Pixel index.
        index: usize,
    },
}

/// Options of [`compare`].
#[derive(Clone, Copy, Debug, Default)]
pub struct CompareOptions<'a> {
    /// Pixels to compare (`true`); `None` compares all.
    pub mask: Option<&'a [bool]>,
    /// A pixel is "wrong" when its largest channel error exceeds this (default 0: any error).
    pub threshold: f32,
}

/// Error of one image against a reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ImageError {
    /// Root mean square error over compared channels.
    pub rmse: f64,
    /// `10·log10(1/MSE)` dB (infinite for identical images).
    pub psnr_db: f64,
    /// Largest absolute channel error.
    pub max_abs: f64,
    /// Share of compared pixels whose largest channel error exceeds the threshold.
    pub share_above: f64,
    /// Pixels compared.
    pub pixels: usize,
}

fn check(a: &RgbaImage, b: &RgbaImage, mask: Option<&[bool]>) -> Result<(), MetricsError> {
    if (a.width, a.height) != (b.width, b.height) || a.pixels.len() != b.pixels.len() {
        return Err(MetricsError::SizeMismatch {
            a: (a.width, a.height),
            b: (b.width, b.height),
        });
    }
    if let Some(m) = mask
        && m.len() != a.pixels.len()
    {
        return Err(MetricsError::MaskSize {
            mask: m.len(),
            pixels: a.pixels.len(),
        });
    }
    for (which, img) in [("first", a), ("second", b)] {
        if let Some(index) = img
            .pixels
            .iter()
            .position(|p| p.iter().any(|c| !c.is_finite()))
        {
            return Err(MetricsError::NonFinite { which, index });
        }
    }
    Ok(())
}

/// Compares `image` with `reference`. Cost: one pass over the pixels.
///
/// Errors: sizes differ, mask size, non-finite pixels, no pixel compared, or
/// [`MetricsError::NothingVisible`] when every compared pixel of both images is zero.
pub fn compare(
    image: &RgbaImage,
    reference: &RgbaImage,
    options: &CompareOptions,
) -> Result<ImageError, MetricsError> {
    check(image, reference, options.mask)?;
    let (mut sum2, mut max_abs, mut above, mut n) = (0.0f64, 0.0f64, 0usize, 0usize);
    let mut visible = false;
    for (k, (p, q)) in image.pixels.iter().zip(&reference.pixels).enumerate() {
        if options.mask.is_some_and(|m| !m[k]) {
            continue;
        }
        n += 1;
        visible |= p.iter().chain(q).any(|c| *c != 0.0);
        let mut worst = 0.0f64;
        for c in 0..4 {
            let e = f64::from(p[c] - q[c]).abs();
            sum2 += e * e;
            worst = worst.max(e);
        }
        max_abs = max_abs.max(worst);
        above += usize::from(worst > f64::from(options.threshold));
    }
    if n == 0 {
        return Err(MetricsError::NothingToCompare);
    }
    if !visible {
        return Err(MetricsError::NothingVisible);
    }
    let mse = sum2 / (4 * n) as f64;
    Ok(ImageError {
        rmse: mse.sqrt(),
        psnr_db: psnr_from_mse(mse),
        max_abs,
        share_above: above as f64 / n as f64,
        pixels: n,
    })
}

/// PSNR in dB for a peak of 1: `10·log10(1/mse)`, infinite when `mse = 0`.
pub fn psnr_from_mse(mse: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

/// PSNR of `image` against `reference` over all pixels (see [`compare`]; two empty pictures are
/// [`MetricsError::NothingVisible`]).
pub fn psnr(image: &RgbaImage, reference: &RgbaImage) -> Result<f64, MetricsError> {
    compare(image, reference, &CompareOptions::default()).map(|e| e.psnr_db)
}

/// Coverage error: the mean absolute difference of alpha between `a` and `b` over the pixels
/// that either covers (alpha > 0), so the empty background does not dilute it. In `[0, 1]`: 0
/// when both pictures cover the same pixels equally, 1 when they cover disjoint pixels fully.
/// Two empty pictures are [`MetricsError::NothingVisible`], not an error of 0. Cost: one pass.
pub fn coverage_error(a: &RgbaImage, b: &RgbaImage) -> Result<f64, MetricsError> {
    check(a, b, None)?;
    let (mut sum, mut covered) = (0.0f64, 0usize);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        if p[3] > 0.0 || q[3] > 0.0 {
            sum += f64::from((p[3] - q[3]).abs());
            covered += 1;
        }
    }
    if covered == 0 {
        return Err(MetricsError::NothingVisible);
    }
    Ok(sum / covered as f64)
}

/// Silhouette intersection over union: pixels with `alpha > alpha_threshold` form each
/// silhouette. Two empty silhouettes are [`MetricsError::NothingVisible`], not an IoU of 1.
pub fn silhouette_iou(
    a: &RgbaImage,
    b: &RgbaImage,
    alpha_threshold: f32,
) -> Result<f64, MetricsError> {
    check(a, b, None)?;
    let (mut inter, mut union) = (0usize, 0usize);
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        let (x, y) = (p[3] > alpha_threshold, q[3] > alpha_threshold);
        inter += usize::from(x && y);
        union += usize::from(x || y);
    }
    if union == 0 {
        return Err(MetricsError::NothingVisible);
    }
    Ok(inter as f64 / union as f64)
}

/// PSNR of the colour alone: over the pixels both pictures cover fully (alpha ≥ 0.999), the
/// RGB error of their colours (premultiplied values divided by alpha), peak 1. Coverage is
/// measured apart ([`coverage_error`], [`silhouette_iou`]), so an outline drawn a pixel off
/// does not count here, and a colour error inside the object is not diluted by the background.
/// Cost: one pass.
///
/// Errors: as [`compare`]; [`MetricsError::NothingToCompare`] when no pixel is covered fully
/// by both pictures.
pub fn colour_psnr(image: &RgbaImage, reference: &RgbaImage) -> Result<f64, MetricsError> {
    check(image, reference, None)?;
    const FULL: f32 = 0.999;
    let (mut sum2, mut n) = (0.0f64, 0usize);
    for (p, q) in image.pixels.iter().zip(&reference.pixels) {
        if p[3] < FULL || q[3] < FULL {
            continue;
        }
        for c in 0..3 {
            let e = f64::from(p[c] / p[3] - q[c] / q[3]);
            sum2 += e * e;
        }
        n += 1;
    }
    if n == 0 {
        return Err(MetricsError::NothingToCompare);
    }
    Ok(psnr_from_mse(sum2 / (3 * n) as f64))
}

/// Pixels per degree of visual angle at which [`flip_mean`] compares pictures: FLIP's default, a
/// 0.7 m view of a 0.7 m wide screen of 3840 pixels.
pub const FLIP_PIXELS_PER_DEGREE: f32 = nv_flip::DEFAULT_PIXELS_PER_DEGREE;

/// The mean FLIP error (Andersson et al. 2020, "FLIP: A Difference Evaluator for Alternating
/// Images", its LDR form through the `nv-flip` crate) of `image` against `reference`: each
/// picture's premultiplied colour (the picture composited over black) encoded to 8-bit sRGB,
/// compared at [`FLIP_PIXELS_PER_DEGREE`], the per-pixel error (in `[0, 1]`, 0 where a viewer
/// flipping between the two sees no difference) averaged over all pixels, as PSNR averages its
/// error over them. Lower is better; it weighs colour and edge differences as a viewer sees
/// them, where PSNR weighs every channel error alike. Alpha is not compared apart from the
/// colour it darkens. Cost: FLIP's spatial filters over the picture, a few passes of
/// `O(pixels)` each.
///
/// Errors: as [`compare`] (sizes, non-finite pixels, an empty picture, both pictures empty).
pub fn flip_mean(image: &RgbaImage, reference: &RgbaImage) -> Result<f64, MetricsError> {
    check(image, reference, None)?;
    if image.pixels.is_empty() {
        return Err(MetricsError::NothingToCompare);
    }
    let visible = |img: &RgbaImage| img.pixels.iter().any(|p| p.iter().any(|c| *c != 0.0));
    if !visible(image) && !visible(reference) {
        return Err(MetricsError::NothingVisible);
    }
    // The picture over black (its premultiplied colour, opaque) as sRGB8, alpha dropped.
    let srgb8 = |img: &RgbaImage| -> Vec<u8> {
        img.over([0.0; 3])
            .srgb8_codes()
            .chunks_exact(4)
            .flat_map(|c| [c[0], c[1], c[2]])
            .collect()
    };
    let (w, h) = (image.width as u32, image.height as u32);
    let test = nv_flip::FlipImageRgb8::with_data(w, h, &srgb8(image));
    let refr = nv_flip::FlipImageRgb8::with_data(w, h, &srgb8(reference));
    let map = nv_flip::flip(refr, test, FLIP_PIXELS_PER_DEGREE);
    Ok(f64::from(nv_flip::FlipPool::from_image(&map).mean()))
}

/// Where the error of an image lies, by the distance of each pixel to the true silhouette: the
/// Chebyshev distance `d` to the nearest pixel on the other side of the ground truth's outline
/// (alpha > ½), up to 2. Each `*_mse` is the squared error summed over that region's pixels and
/// channels divided by all of them (`4 × pixels`), so the four parts add up to the image's MSE.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ErrorSplit {
    /// Pixels with `d ≤ 1` (the silhouette band of one pixel either side).
    pub band1_mse: f64,
    /// Pixels with `d = 2`.
    pub band2_mse: f64,
    /// Covered pixels further in (`d > 2`).
    pub interior_mse: f64,
    /// Uncovered pixels further out (`d > 2`): false coverage far from the outline.
    pub outside_mse: f64,
    /// Mean alpha of the image minus that of the truth (positive: over-coverage).
    pub alpha_bias: f64,
}

impl ErrorSplit {
    /// The sum of the parts, the image's MSE.
    pub fn mse(&self) -> f64 {
        self.band1_mse + self.band2_mse + self.interior_mse + self.outside_mse
    }

    /// Adds `o` part by part (to average several images with [`Self::scale`]).
    pub fn add(&mut self, o: &Self) {
        self.band1_mse += o.band1_mse;
        self.band2_mse += o.band2_mse;
        self.interior_mse += o.interior_mse;
        self.outside_mse += o.outside_mse;
        self.alpha_bias += o.alpha_bias;
    }

    /// Multiplies every part by `f`.
    pub fn scale(&mut self, f: f64) {
        self.band1_mse *= f;
        self.band2_mse *= f;
        self.interior_mse *= f;
        self.outside_mse *= f;
        self.alpha_bias *= f;
    }
}

/// Splits the error of `image` against `truth` by distance to the true silhouette (see
/// [`ErrorSplit`]). Cost: 25 look-ups per pixel. Errors: images of different sizes, non-finite
/// pixels, or empty images.
pub fn error_split(image: &RgbaImage, truth: &RgbaImage) -> Result<ErrorSplit, MetricsError> {
    check(image, truth, None)?;
    let (w, h) = (truth.width, truth.height);
    if w * h == 0 {
        return Err(MetricsError::NothingToCompare);
    }
    let inside = |i: i64, j: i64| {
        let (i, j) = (i.clamp(0, w as i64 - 1), j.clamp(0, h as i64 - 1));
        truth.pixels[j as usize * w + i as usize][3] > 0.5
    };
    let mut out = ErrorSplit::default();
    let norm = 1.0 / (4 * w * h) as f64;
    for j in 0..h as i64 {
        for i in 0..w as i64 {
            let me = inside(i, j);
            let mut d = 3;
            for dj in -2i64..=2 {
                for di in -2i64..=2 {
                    if inside(i + di, j + dj) != me {
                        d = d.min(di.abs().max(dj.abs()));
                    }
                }
            }
            let k = j as usize * w + i as usize;
            let (a, b) = (image.pixels[k], truth.pixels[k]);
            let e2: f64 = (0..4).map(|c| f64::from(a[c] - b[c]).powi(2)).sum::<f64>() * norm;
            match (d, me) {
                (0..=1, _) => out.band1_mse += e2,
                (2, _) => out.band2_mse += e2,
                (_, true) => out.interior_mse += e2,
                (_, false) => out.outside_mse += e2,
            }
            out.alpha_bias += f64::from(a[3] - b[3]) / (w * h) as f64;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn img(pixels: Vec<[f32; 4]>, w: usize) -> RgbaImage {
        RgbaImage {
            width: w,
            height: pixels.len() / w,
            pixels,
        }
    }

    /// Colour PSNR: only pixels both cover fully count, and there the colour error alone.
    #[test]
    fn colour_psnr_compares_colour_where_both_cover() {
        // Pixel 0 both full (colour off by 0.1 in red), pixel 1 covered by one only (ignored),
        // pixel 2 half covered in both (ignored), pixel 3 empty in both.
        let a = img(
            vec![
                [0.6, 0.2, 0.2, 1.0],
                [1.0; 4],
                [0.2, 0.2, 0.2, 0.5],
                [0.0; 4],
            ],
            2,
        );
        let b = img(
            vec![
                [0.5, 0.2, 0.2, 1.0],
                [0.0; 4],
                [0.4, 0.4, 0.4, 0.5],
                [0.0; 4],
            ],
            2,
        );
        let want = 10.0 * (3.0f64 / 0.01).log10();
        assert_abs_diff_eq!(colour_psnr(&a, &b).unwrap(), want, epsilon = 1e-4);
        assert_eq!(colour_psnr(&a, &a).unwrap(), f64::INFINITY);
        let half = img(vec![[0.2, 0.2, 0.2, 0.5]; 4], 2);
        assert_eq!(colour_psnr(&half, &b), Err(MetricsError::NothingToCompare));
    }

    /// FLIP: 0 for identical pictures, in (0, 1] for different ones and growing with the
    /// difference, symmetric in its range; typed errors for empty, mismatched and non-finite
    /// pictures.
    #[test]
    fn flip_is_zero_for_equal_pictures_and_grows_with_the_difference() {
        let n = 32;
        let grey = |v: f32| img(vec![[v, v, v, 1.0]; n * n], n);
        let disc = |v: f32| {
            let pixels = (0..n * n)
                .map(|k| {
                    let (x, y) = ((k % n) as f32 - 15.5, (k / n) as f32 - 15.5);
                    if x.hypot(y) < 10.0 {
                        [v, 0.2, 0.1, 1.0]
                    } else {
                        [0.0; 4]
                    }
                })
                .collect();
            img(pixels, n)
        };
        assert_eq!(flip_mean(&disc(0.5), &disc(0.5)).unwrap(), 0.0);
        let small = flip_mean(&disc(0.55), &disc(0.5)).unwrap();
        let large = flip_mean(&disc(0.9), &disc(0.5)).unwrap();
        assert!(
            small > 0.0 && small < large && large <= 1.0,
            "{small} {large}"
        );
        assert!(flip_mean(&grey(1.0), &grey(0.0)).unwrap() > 0.5);
        let empty = img(vec![[0.0; 4]; n * n], n);
        assert_eq!(flip_mean(&empty, &empty), Err(MetricsError::NothingVisible));
        assert!(matches!(
            flip_mean(&grey(0.5), &img(vec![[0.5; 4]; 4], 2)),
            Err(MetricsError::SizeMismatch { .. })
        ));
        assert!(matches!(
            flip_mean(&grey(f32::NAN), &grey(0.5)),
            Err(MetricsError::NonFinite { .. })
        ));
        assert_eq!(
            flip_mean(&img(Vec::new(), 1), &img(Vec::new(), 1)),
            Err(MetricsError::NothingToCompare)
        );
    }

    #[test]
    fn known_errors() {
        let a = img(vec![[0.0; 4], [1.0; 4]], 2);
        let b = img(vec![[0.0; 4], [0.5, 1.0, 1.0, 1.0]], 2);
        let e = compare(
            &a,
            &b,
            &CompareOptions {
                mask: None,
                threshold: 0.1,
            },
        )
        .unwrap();
        // One channel off by 0.5 among 8: MSE = 0.25/8.
        assert!((e.rmse - (0.25f64 / 8.0).sqrt()).abs() < 1e-12);
        assert!((e.psnr_db - 10.0 * (8.0f64 / 0.25).log10()).abs() < 1e-9);
        assert_eq!(e.max_abs, 0.5);
        assert_eq!(e.share_above, 0.5);
        // Masking the wrong pixel out leaves identical images: infinite PSNR when something is
        // visible, no figure at all when the compared pixels are empty in both.
        let m = [false, true];
        let c = img(vec![[0.0; 4], [0.5, 1.0, 1.0, 1.0]], 2);
        let e = compare(
            &c,
            &b,
            &CompareOptions {
                mask: Some(&m),
                threshold: 0.0,
            },
        )
        .unwrap();
        assert_eq!(e.psnr_db, f64::INFINITY);
        assert_eq!(e.pixels, 1);
        let m = [true, false];
        assert_eq!(
            compare(
                &a,
                &b,
                &CompareOptions {
                    mask: Some(&m),
                    threshold: 0.0,
                },
            ),
            Err(MetricsError::NothingVisible)
        );
    }

    /// An object no view sees gives two empty pictures: an error, never PSNR ∞ or IoU 1; one
    /// empty side is a real (finite) error.
    #[test]
    fn empty_pictures_are_not_a_perfect_score() {
        let empty = img(vec![[0.0; 4]; 4], 2);
        assert_eq!(psnr(&empty, &empty), Err(MetricsError::NothingVisible));
        assert_eq!(
            silhouette_iou(&empty, &empty, 0.5),
            Err(MetricsError::NothingVisible)
        );
        let one = img(vec![[0.0; 4], [0.0; 4], [0.0; 4], [1.0; 4]], 2);
        // One pixel of four wrong by 1 in all channels: MSE 1/4.
        approx::assert_relative_eq!(
            psnr(&one, &empty).unwrap(),
            10.0 * 4.0f64.log10(),
            epsilon = 1e-12
        );
        assert_eq!(silhouette_iou(&one, &empty, 0.5), Ok(0.0));
    }

    #[test]
    fn iou_and_errors() {
        let a = img(
            vec![[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0], [0.0; 4]],
            3,
        );
        let b = img(
            vec![[0.0, 0.0, 0.0, 1.0], [0.0; 4], [0.0, 0.0, 0.0, 1.0]],
            3,
        );
        assert!((silhouette_iou(&a, &b, 0.5).unwrap() - 1.0 / 3.0).abs() < 1e-12);
        let c = img(vec![[0.0; 4]; 2], 2);
        assert!(matches!(
            compare(&a, &c, &CompareOptions::default()),
            Err(MetricsError::SizeMismatch { .. })
        ));
        let m = [false; 3];
        assert_eq!(
            compare(
                &a,
                &b,
                &CompareOptions {
                    mask: Some(&m),
                    threshold: 0.0
                }
            ),
            Err(MetricsError::NothingToCompare)
        );
        let m = [true; 2];
        assert!(matches!(
            compare(
                &a,
                &b,
                &CompareOptions {
                    mask: Some(&m),
                    threshold: 0.0
                }
            ),
            Err(MetricsError::MaskSize { .. })
        ));
        let n = img(vec![[f32::NAN, 0.0, 0.0, 1.0], [0.0; 4], [0.0; 4]], 3);
        assert!(matches!(
            psnr(&n, &b),
            Err(MetricsError::NonFinite {
                which: "first",
                index: 0
            })
        ));
    }
}
