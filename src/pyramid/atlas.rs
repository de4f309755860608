//! Atlases of frames (the views of an impostor) whose mip levels do not bleed into each other.
//!
//! ## Layout
//! `N` frames of `w × h` texels sit in a grid of `cols × rows` cells (`cols = ⌈√N⌉`), row-major,
//! frame `k` in cell `(k mod cols, ⌊k/cols⌋)`. Each cell is the frame with a gutter of `g` texels
//! on its left and top and at least `g` on its right and bottom, the cell sides rounded up to a
//! multiple of `2^L`, where `L` is the last level that must stay clean ([`AtlasLayout::clean_levels`]).
//!
//! ## Why no bleeding up to level `L`
//! Cell sides and origins are multiples of `2^L`, so the atlas sides are too and every level
//! `l ≤ L` is an exact halving (`s = 2^l` level-0 texels per level-`l` texel, no cut texel). A
//! level-`l` texel whose footprint touches frame `k` has its centre at most `2^(l−1)` beyond the
//! frame's edge and reads level 0 within `r·2^l` of its centre ([`super::filter::radius`] `r`), so
//! everything it reads lies in the frame's cell when `g ≥ 2^(l−1)·(1 + 2r)`. The gutter is
//! `g = 2^L·⌈(1 + 2r)/2⌉` (`2^L` for box and triangle, `4·2^L` for Kaiser and Lanczos): a multiple of
//! `2^L`, so frames are aligned too, and at level `L` a box-filtered frame keeps at least one
//! texel of its own gutter around it for bilinear lookups. Frames are therefore filtered exactly
//! as alone: with the box filter, frame `k`'s texels at level `l` equal the level `l` of frame `k`
//! alone under the gutter's fill (transparent = zero outside, edge-replicated = clamp).
//!
//! Gutter fill ([`GutterFill`]): transparent (zero in every channel, i.e. premultiplied
//! transparent black) or edge-replicated (each gutter texel copies the nearest frame texel).
//!
//! Cost: packing is one copy of the frames plus the gutters; the atlas is
//! `cols·cell_w × rows·cell_h` texels.

use rayon::prelude::*;

use super::filter::radius;
use super::mip::{Filter, MipError, Texture};

/// What the gutter around each frame holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum GutterFill {
    /// Zero in every channel (transparent, premultiplied).
    Transparent,
    /// The nearest frame texel (edge replication, as clamp-to-edge on the frame alone).
    Replicate,
}

/// Where every frame sits in an atlas (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct AtlasLayout {
    /// Number of frames.
    pub frames: usize,
    /// Frame width, texels.
    pub frame_w: usize,
    /// Frame height, texels.
    pub frame_h: usize,
    /// Gutter on the left and top of each frame (at least this on the right and bottom), texels.
    pub gutter: usize,
    /// Cells per row.
    pub cols: usize,
    /// Rows of cells.
    pub rows: usize,
    /// Cell width (a multiple of `2^clean_levels`), texels.
    pub cell_w: usize,
    /// Cell height (a multiple of `2^clean_levels`), texels.
    pub cell_h: usize,
    /// Levels `1 … clean_levels` do not bleed between frames under the filter the layout was
    /// made for.
    pub clean_levels: usize,
}

impl AtlasLayout {
    /// The layout for `frames` frames of `frame_w × frame_h` whose levels up to `clean_levels`
    /// (at most 16) do not bleed under `filter`. Errors: a zero count or size, more than 16
    /// levels, or an atlas side beyond 2^20 texels.
    pub fn new(
        frames: usize,
        frame_w: usize,
        frame_h: usize,
        clean_levels: usize,
        filter: Filter,
    ) -> Result<Self, MipError> {
        if frames == 0 {
            return Err(MipError::InvalidParams {
                name: "frames",
                reason: "must be at least 1",
            });
        }
        for (n, what) in [(frame_w, "width"), (frame_h, "height")] {
            if n == 0 {
                return Err(MipError::ZeroSize { what });
            }
        }
        if clean_levels > 16 {
            return Err(MipError::InvalidParams {
                name: "clean_levels",
                reason: "must be at most 16",
            });
        }
        let step = 1usize << clean_levels;
        let gutter = if clean_levels == 0 {
            0
        } else {
            step * ((1.0 + 2.0 * radius(filter)) / 2.0).ceil() as usize
        };
        let round = |n: usize| n.div_ceil(step) * step;
        let (cell_w, cell_h) = (round(frame_w + 2 * gutter), round(frame_h + 2 * gutter));
        let cols = (frames as f64).sqrt().ceil() as usize;
        let rows = frames.div_ceil(cols);
        if cols * cell_w > 1 << 20 || rows * cell_h > 1 << 20 {
            return Err(MipError::InvalidParams {
                name: "frames",
                reason: "the atlas would exceed 2^20 texels per side",
            });
        }
        Ok(Self {
            frames,
            frame_w,
            frame_h,
            gutter,
            cols,
            rows,
            cell_w,
            cell_h,
            clean_levels,
        })
    }

    /// A naive atlas: frames side by side, no gutter, no alignment (for comparison: its levels
    /// bleed).
    pub fn naive(frames: usize, frame_w: usize, frame_h: usize) -> Result<Self, MipError> {
        let mut l = Self::new(frames, frame_w, frame_h, 0, Filter::Box)?;
        l.cell_w = frame_w;
        l.cell_h = frame_h;
        Ok(l)
    }

    /// Atlas width, texels.
    pub fn width(&self) -> usize {
        self.cols * self.cell_w
    }

    /// Atlas height, texels.
    pub fn height(&self) -> usize {
        self.rows * self.cell_h
    }

    /// Top-left texel of frame `k` in level 0.
    pub fn origin(&self, k: usize) -> (usize, usize) {
        (
            (k % self.cols) * self.cell_w + self.gutter,
            (k / self.cols) * self.cell_h + self.gutter,
        )
    }

    /// Texel rectangle `[x0, x1) × [y0, y1)` of level `level` (of an atlas of `w × h` at that
    /// level) whose footprints touch frame `k`.
    pub fn frame_rect(&self, k: usize, level: usize, w: usize, h: usize) -> [usize; 4] {
        let (x, y) = self.origin(k);
        let s = 1usize << level;
        [
            (x / s).min(w - 1),
            (y / s).min(h - 1),
            (x + self.frame_w).div_ceil(s).clamp(1, w),
            (y + self.frame_h).div_ceil(s).clamp(1, h),
        ]
    }

    /// The atlas of `frames` (each `frame_w × frame_h`, same channel count) with gutters filled
    /// by `fill`; cells without a frame are zero. Errors: wrong number or size of frames.
    pub fn pack(&self, frames: &[Texture], fill: GutterFill) -> Result<Texture, MipError> {
        if frames.len() != self.frames {
            return Err(MipError::InvalidParams {
                name: "frames",
                reason: "count differs from the layout's",
            });
        }
        let c = frames[0].channels;
        if frames
            .iter()
            .any(|f| f.width != self.frame_w || f.height != self.frame_h || f.channels != c)
        {
            return Err(MipError::InvalidParams {
                name: "frames",
                reason: "a frame's size or channel count differs from the layout's",
            });
        }
        let (w, h) = (self.width(), self.height());
        let mut data = vec![0.0f32; w * h * c];
        data.par_chunks_mut(w * c).enumerate().for_each(|(y, row)| {
            let cy = y / self.cell_h;
            for cx in 0..self.cols {
                let k = cy * self.cols + cx;
                let Some(f) = frames.get(k) else { continue };
                let (ox, oy) = self.origin(k);
                let fy = y as i64 - oy as i64;
                let inside_y = (0..self.frame_h as i64).contains(&fy);
                if !inside_y && fill == GutterFill::Transparent {
                    continue;
                }
                let sy = fy.clamp(0, self.frame_h as i64 - 1) as usize;
                for x in cx * self.cell_w..(cx + 1) * self.cell_w {
                    let fx = x as i64 - ox as i64;
                    let inside_x = (0..self.frame_w as i64).contains(&fx);
                    if !inside_x && fill == GutterFill::Transparent {
                        continue;
                    }
                    let sx = fx.clamp(0, self.frame_w as i64 - 1) as usize;
                    row[x * c..(x + 1) * c].copy_from_slice(f.texel(sx, sy));
                }
            }
        });
        Texture::new(w, h, c, data)
    }

    /// Frame `k`'s texels at one level of an atlas pyramid (the rectangle of
    /// [`AtlasLayout::frame_rect`]), row-major.
    pub fn unpack(&self, level_tex: &Texture, k: usize, level: usize) -> Texture {
        let [x0, y0, x1, y1] = self.frame_rect(k, level, level_tex.width, level_tex.height);
        let c = level_tex.channels;
        let mut data = Vec::with_capacity((x1 - x0) * (y1 - y0) * c);
        for y in y0..y1 {
            for x in x0..x1 {
                data.extend_from_slice(level_tex.texel(x, y));
            }
        }
        Texture {
            width: x1 - x0,
            height: y1 - y0,
            channels: c,
            data,
        }
    }
}

/// Bleeding per level: for every level of the atlas pyramid, the largest change of a texel of
/// some frame `k` when every other frame is replaced by zeros (`max |A − A_k|` over `k` and over
/// frame `k`'s texels). Zero means no frame's levels depend on another frame. Cost: `N + 1`
/// pyramid builds of the atlas.
pub fn bleed(
    layout: &AtlasLayout,
    frames: &[Texture],
    fill: GutterFill,
    params: super::PyramidParams,
) -> Result<Vec<f64>, MipError> {
    let full = super::Pyramid::build(layout.pack(frames, fill)?, params)?;
    let mut worst = vec![0.0f64; full.levels().len()];
    for k in 0..frames.len() {
        let alone: Vec<Texture> = frames
            .iter()
            .enumerate()
            .map(|(j, f)| {
                if j == k {
                    f.clone()
                } else {
                    Texture {
                        data: vec![0.0; f.data.len()],
                        ..f.clone()
                    }
                }
            })
            .collect();
        let only = super::Pyramid::build(layout.pack(&alone, fill)?, params)?;
        for (l, (a, b)) in full.levels().iter().zip(only.levels()).enumerate() {
            let (ua, ub) = (layout.unpack(a, k, l), layout.unpack(b, k, l));
            let d = ua
                .data
                .iter()
                .zip(&ub.data)
                .map(|(x, y)| f64::from((x - y).abs()))
                .fold(0.0, f64::max);
            worst[l] = worst[l].max(d);
        }
    }
    Ok(worst)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pyramid::{AlphaMode, ColourSpace, Pyramid, PyramidParams, WrapMode};

    /// Distinct frames: frame `k` is a noisy pattern of its own brightness, opaque in its
    /// middle, transparent at its corners.
    fn frames(n: usize, w: usize, h: usize) -> Vec<Texture> {
        (0..n)
            .map(|k| {
                let mut d = Vec::with_capacity(w * h * 4);
                for y in 0..h {
                    for x in 0..w {
                        let noise = ((x * 31 + y * 17 + k * 7) % 13) as f32 / 12.0;
                        let a = if (x == 0 || x == w - 1) && (y == 0 || y == h - 1) {
                            0.0
                        } else {
                            1.0
                        };
                        let v = (0.2 * k as f32 + 0.5 * noise).min(1.0) * a;
                        d.extend([v, 1.0 - v, 0.5 * v, a]);
                    }
                }
                Texture::new(w, h, 4, d).unwrap()
            })
            .collect()
    }

    #[test]
    fn gutters_stop_bleeding_up_to_the_stated_level_and_a_naive_atlas_bleeds() {
        let (n, w, h) = (5, 24, 20);
        let fr = frames(n, w, h);
        for filter in [Filter::Box, Filter::Kaiser] {
            let p = PyramidParams {
                filter,
                colour: ColourSpace::Srgb,
                alpha: AlphaMode::Premultiplied,
                ..Default::default()
            };
            for fill in [GutterFill::Transparent, GutterFill::Replicate] {
                let layout = AtlasLayout::new(n, w, h, 3, filter).unwrap();
                assert_eq!(layout.width() % 8, 0);
                let b = bleed(&layout, &fr, fill, p).unwrap();
                for (l, &d) in b.iter().enumerate().take(4) {
                    assert_eq!(d, 0.0, "{filter:?} {fill:?} level {l}: bleed {d}");
                }
                // Beyond the stated level the cells merge: some bleeding appears.
                assert!(b.iter().skip(4).any(|&d| d > 1e-3), "{b:?}");
            }
            // Without gutters, level 1 already mixes frames (24 and 20 are even, so the box
            // filter only bleeds once a level's texels straddle two frames: level 3 for box).
            let naive = AtlasLayout::naive(n, w, h).unwrap();
            let b = bleed(&naive, &fr, GutterFill::Transparent, p).unwrap();
            let first = if filter == Filter::Box { 3 } else { 1 };
            assert!(b[first] > 1e-2, "{filter:?}: naive bleed {b:?}");
        }
    }

    /// With the box filter, a frame's levels in a transparent-gutter atlas are the levels of the
    /// frame alone padded by zeros; with replicated gutters, of the frame alone under clamp.
    #[test]
    fn box_levels_equal_the_frame_alone() {
        let (n, w, h) = (3, 16, 16);
        let fr = frames(n, w, h);
        let p = PyramidParams::default();
        let layout = AtlasLayout::new(n, w, h, 2, Filter::Box).unwrap();
        let atlas = Pyramid::build(layout.pack(&fr, GutterFill::Replicate).unwrap(), p).unwrap();
        for (k, f) in fr.iter().enumerate() {
            let alone = Pyramid::build(
                f.clone(),
                PyramidParams {
                    wrap: [WrapMode::Clamp; 2],
                    ..p
                },
            )
            .unwrap();
            for l in 0..=2 {
                let got = layout.unpack(&atlas.levels()[l], k, l);
                let want = &alone.levels()[l];
                assert_eq!((got.width, got.height), (want.width, want.height));
                for (a, b) in got.data.iter().zip(&want.data) {
                    approx::assert_abs_diff_eq!(a, b, epsilon = 1e-6);
                }
            }
        }
    }

    #[test]
    fn bad_layouts_are_typed_errors() {
        assert!(AtlasLayout::new(0, 4, 4, 1, Filter::Box).is_err());
        assert!(AtlasLayout::new(2, 0, 4, 1, Filter::Box).is_err());
        assert!(AtlasLayout::new(2, 4, 4, 17, Filter::Box).is_err());
        let l = AtlasLayout::new(2, 4, 4, 1, Filter::Box).unwrap();
        assert!(l.pack(&frames(3, 4, 4), GutterFill::Transparent).is_err());
        assert!(l.pack(&frames(2, 5, 4), GutterFill::Transparent).is_err());
    }
}
