//! # altrep-compare: the libraries altrep is measured against
//!
//! `altrep pyramid-bench` and `cargo bench -p altrep-benches --bench pyramid` time altrep's RGBA8 sRGB mip-chain
//! builder against `fast_image_resize`. That crate's resizer is generic over every pixel type
//! and filter, and whoever calls it compiles its SIMD kernels again (about a third of the
//! library's generated code when it lived there). Behind the plain functions of this crate they
//! are compiled once, beside the library, and not again in each of its test builds. Its tests
//! live with the caller (`altrep::pyramid::speed`): this crate has no test build of its own.

#![warn(missing_docs)]

use fast_image_resize as fir;
use rayon::prelude::*;

/// The resampling filter of [`fir_mip_chain`].
#[derive(Clone, Copy, Debug)]
pub enum ChainFilter {
    /// `fast_image_resize`'s box filter.
    Box,
    /// Its bilinear (triangle) filter.
    Bilinear,
    /// Its Lanczos-3 filter.
    Lanczos3,
    /// A custom kernel `kernel(x)` of support `support` (texels of the source, each side),
    /// point-sampled by the resizer.
    Custom {
        /// The kernel.
        kernel: fn(f64) -> f64,
        /// Its support radius.
        support: f64,
    },
}

/// The sizes of the levels below an `n × n` level 0: halved (rounded down, at least 1) until
/// `1 × 1`.
pub fn level_sizes(n: usize) -> Vec<(usize, usize)> {
    let (mut w, mut h) = (n, n);
    let mut s = Vec::new();
    while w > 1 || h > 1 {
        (w, h) = ((w / 2).max(1), (h / 2).max(1));
        s.push((w, h));
    }
    s
}

/// The RGBA8 sRGB mip chain of the `n × n` image `src` (row-major RGBA8, straight alpha) by
/// `fast_image_resize`, levels 1… (see [`level_sizes`]): level 0 mapped once from sRGB8 to
/// linear 16-bit with its sRGB mapper (alpha not mapped), each level resized from it by
/// convolution with `filter` (alpha multiplied and divided by the resizer), mapped back to
/// sRGB8. Levels in parallel (rayon), one resizer each. Errors: the crate's message.
pub fn fir_mip_chain(src: &[u8], n: usize, filter: ChainFilter) -> Result<Vec<Vec<u8>>, String> {
    let alg = match filter {
        ChainFilter::Box => fir::FilterType::Box,
        ChainFilter::Bilinear => fir::FilterType::Bilinear,
        ChainFilter::Lanczos3 => fir::FilterType::Lanczos3,
        ChainFilter::Custom { kernel, support } => fir::FilterType::Custom(
            fir::Filter::new("custom", kernel, support).map_err(|e| e.to_string())?,
        ),
    };
    let mapper = fir::create_srgb_mapper();
    let side = u32::try_from(n).map_err(|e| e.to_string())?;
    let src = fir::images::ImageRef::new(side, side, src, fir::PixelType::U8x4)
        .map_err(|e| e.to_string())?;
    let mut lin = fir::images::Image::new(side, side, fir::PixelType::U16x4);
    mapper
        .forward_map(&src, &mut lin)
        .map_err(|e| e.to_string())?;
    let opts = fir::ResizeOptions::new().resize_alg(fir::ResizeAlg::Convolution(alg));
    level_sizes(n)
        .into_par_iter()
        .map(|(w, h)| {
            let (w, h) = (w as u32, h as u32);
            let mut resizer = fir::Resizer::new();
            let mut dst = fir::images::Image::new(w, h, fir::PixelType::U16x4);
            resizer
                .resize(&lin, &mut dst, &opts)
                .map_err(|e| e.to_string())?;
            let mut dst8 = fir::images::Image::new(w, h, fir::PixelType::U8x4);
            mapper
                .backward_map(&dst, &mut dst8)
                .map_err(|e| e.to_string())?;
            Ok(dst8.into_vec())
        })
        .collect()
}
