//! Slices holding one object instead of a tile (docs/design.md §9.4): the object's box is
//! voxelised (not repeated), cut into stacks like a tile, and drawn from any direction in an
//! orthographic frame of data-gen ([`OrthoFrame`]), as a display draws the slice polygons that
//! fill the box: per pixel, the slices of the chosen stack its ray crosses inside the box,
//! nearest in front, each read with trilinear 2D filtering at the pixel's footprint and its
//! opacity raised to the path length (the module conventions).
//!
//! The box is `[min, min + dims·s]` in the frame's world coordinates; a slice texel `(i, j)`
//! of axis `a` covers the box's voxels `u = i`, `v = j` along [`Axis::plane_axes`]. Outside the
//! box nothing is drawn.

use altrep_data_gen::{OrthoFrame, RgbaImage, Supersample};
use glam::DVec3;
use rayon::prelude::*;

use super::merge::{Side, SliceData};
use super::render::{accumulate, trilinear_into};
use super::stack::{ViewChoice, check_view, choose_direction, level_for_slices, slices_needed};
use super::volume::rescale_thickness;
use super::{Axis, SliceError};

/// An image of the object drawn from its slices, with what it cost.
#[derive(Clone, Debug)]
pub struct ObjectImage {
    /// Premultiplied linear RGBA, `width × height`.
    pub image: RgbaImage,
    /// Slice reads per covered pixel (the slices a display's fragments composite, after early
    /// termination at opacity `1 − 10⁻⁶`), averaged over the pixels whose rays cross at least
    /// one slice; 0 when none does.
    pub steps_per_pixel: f64,
    /// Pixels whose rays cross at least one slice.
    pub covered_pixels: usize,
    /// Per pixel (row-major): slices read by its rays, all sub-samples together.
    pub steps: Vec<u32>,
    /// Per pixel: a ray of it crosses at least one slice.
    pub covered: Vec<bool>,
}

/// The stack a display draws for view vector `view` (unit, toward the camera) at visible depth
/// `depth` (world units, the criterion's `d`), among the stacks `data` holds: the direction by
/// the paper's rule among the stored axes, then the level the criterion asks for, or the
/// coarsest stored level finer than it, or else the finest stored level.
///
/// Errors: no stack stored, a zero or non-finite view, a depth that is not positive.
pub fn choose_stored(data: &SliceData, view: DVec3, depth: f64) -> Result<ViewChoice, SliceError> {
    let s = data.voxel_size();
    let axis = choose_direction(view, [s; 3], stored_axes(data))?;
    stored_level(data, axis, view, depth)
}

/// The axes `data` holds a stack of (`x, y, z`).
pub(crate) fn stored_axes(data: &SliceData) -> [bool; 3] {
    let mut allowed = [false; 3];
    for s in data.stacks() {
        allowed[s.axis().index()] = true;
    }
    allowed
}

/// What `data` draws along `axis` for view vector `view` at visible depth `depth`: the level the
/// criterion asks for, or the coarsest stored level finer than it, or else the finest stored
/// level (see [`choose_stored`]). Errors: no stack of `axis`, a zero or non-finite view, a
/// depth that is not positive.
pub(crate) fn stored_level(
    data: &SliceData,
    axis: Axis,
    view: DVec3,
    depth: f64,
) -> Result<ViewChoice, SliceError> {
    check_view(view)?;
    let s = data.voxel_size();
    let i = axis.index();
    let n = data.dims()[i];
    let c = view.normalize()[i].abs().min(1.0);
    let needed = slices_needed(n as f64 * s, c.acos(), depth)?;
    let wanted = level_for_slices(axis, n, needed, false)?;
    let stored: Vec<usize> = data
        .stacks()
        .iter()
        .filter(|s| s.axis() == axis)
        .map(|s| s.level())
        .collect();
    let level = stored
        .iter()
        .copied()
        .filter(|l| *l <= wanted)
        .max()
        .or_else(|| stored.iter().copied().min())
        .ok_or(SliceError::MissingStack {
            axis,
            level: wanted,
        })?;
    Ok(ViewChoice {
        axis,
        level,
        slices: n >> level,
        needed,
    })
}

/// Draws the stack of `axis` at `level` of `data` (a volume that does not tile, see
/// [`super::SliceParams::tiled`]) placed with its lower corner at `min`, in `frame`, `width ×
/// height` pixels with `k × k` sub-samples each. Cost: per sub-sample one or two bilinear reads
/// per slice crossed, rows in parallel.
///
/// Errors: a stack not built, zero sizes, a non-finite corner.
pub fn render_object(
    data: &SliceData,
    (axis, level): (Axis, usize),
    frame: &OrthoFrame,
    min: DVec3,
    (width, height): (usize, usize),
    supersample: Supersample,
) -> Result<ObjectImage, SliceError> {
    if width == 0 || height == 0 {
        return Err(SliceError::ZeroSize { what: "image size" });
    }
    for (k, v) in min.to_array().into_iter().enumerate() {
        if !v.is_finite() {
            return Err(SliceError::NonFinite {
                what: "object box corner",
                index: k,
            });
        }
    }
    let stack = data.stack(axis, level)?;
    let dims = data.dims();
    let extent = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * data.voxel_size();
    let i = axis.index();
    let (ua, va) = axis.plane_axes();
    let v = frame.dir;
    let dir = -v;
    let d_i = dir[i];
    let side = if v[i] > 0.0 { Side::Plus } else { Side::Minus };
    let slices = stack.slices(side);
    let count = slices.len() as i64;
    let h = stack.spacing();
    let ratio = 1.0 / v[i].abs().max(1e-12);
    let k = supersample.get();
    // Footprint of one sub-sample on the slice plane (world units).
    let foot = |e: DVec3| e - (e[i] / d_i) * dir;
    let (fx, fy) = (
        foot(frame.right * (2.0 * frame.radius / (width * k) as f64)),
        foot(frame.up * (2.0 * frame.radius / (height * k) as f64)),
    );
    let norm = 1.0 / (k * k) as f64;
    type Row = (Vec<[f32; 4]>, Vec<u32>, Vec<bool>);
    let rows: Vec<Row> = (0..height)
        .into_par_iter()
        .map(|j| {
            let mut row = vec![[0.0f32; 4]; width];
            let mut steps = vec![0u32; width];
            let mut covered = vec![false; width];
            for (col, px) in row.iter_mut().enumerate() {
                let mut acc_px = [0.0f64; 4];
                let mut crossed = false;
                let mut reads = 0u32;
                for b in 0..k {
                    for a in 0..k {
                        let x =
                            -1.0 + (col as f64 + (a as f64 + 0.5) / k as f64) * 2.0 / width as f64;
                        let y =
                            1.0 - (j as f64 + (b as f64 + 0.5) / k as f64) * 2.0 / height as f64;
                        let o =
                            frame.centre + frame.radius * (x * frame.right + y * frame.up) - min;
                        let Some((t0, t1)) = box_span(o, dir, extent) else {
                            continue;
                        };
                        if d_i.abs() < 1e-12 {
                            continue;
                        }
                        let (qa, qb) = (o[i] + t0 * d_i, o[i] + t1 * d_i);
                        let (lo, hi) = (qa.min(qb), qa.max(qb));
                        let m_lo = ((lo / h - 0.5).ceil() as i64).max(0);
                        let m_hi = ((hi / h - 0.5).floor() as i64).min(count - 1);
                        if m_lo > m_hi {
                            continue;
                        }
                        crossed = true;
                        let mut acc = [0.0f64; 4];
                        let mut out = [0.0f32; 4];
                        for s in 0..=(m_hi - m_lo) {
                            let m = if d_i > 0.0 { m_lo + s } else { m_hi - s };
                            let t = ((m as f64 + 0.5) * h - o[i]) / d_i;
                            let hit = o + t * dir;
                            let (u, w) = (hit[ua] / extent[ua], hit[va] / extent[va]);
                            let pyr = &slices[m as usize];
                            let lod = pyr.lod(
                                fx[ua] / extent[ua],
                                fx[va] / extent[va],
                                fy[ua] / extent[ua],
                                fy[va] / extent[va],
                            );
                            trilinear_into(pyr, lod, u, w, &mut out);
                            reads += 1;
                            if accumulate(&mut acc, rescale_thickness(out.map(f64::from), ratio)) {
                                break;
                            }
                        }
                        for (p, q) in acc_px.iter_mut().zip(acc) {
                            *p += q;
                        }
                    }
                }
                covered[col] = crossed;
                steps[col] = reads;
                *px = acc_px.map(|x| (x * norm) as f32);
            }
            (row, steps, covered)
        })
        .collect();
    let mut image = RgbaImage::new(width, height);
    let mut steps = Vec::with_capacity(width * height);
    let mut covered = Vec::with_capacity(width * height);
    for (j, (row, s, c)) in rows.into_iter().enumerate() {
        image.pixels[j * width..(j + 1) * width].copy_from_slice(&row);
        steps.extend(s);
        covered.extend(c);
    }
    let covered_pixels = covered.iter().filter(|c| **c).count();
    let reads: u64 = steps.iter().map(|&s| u64::from(s)).sum();
    let steps_per_pixel = if covered_pixels > 0 {
        reads as f64 * norm / covered_pixels as f64
    } else {
        0.0
    };
    Ok(ObjectImage {
        image,
        steps_per_pixel,
        covered_pixels,
        steps,
        covered,
    })
}

/// The parameter interval `[t0, t1]` in which the line `o + t·dir` lies inside the box
/// `[0, extent]`, or `None` when it misses it.
fn box_span(o: DVec3, dir: DVec3, extent: DVec3) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if dir[a].abs() < 1e-15 {
            if o[a] < 0.0 || o[a] > extent[a] {
                return None;
            }
            continue;
        }
        let (ta, tb) = (-o[a] / dir[a], (extent[a] - o[a]) / dir[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    (t0 <= t1).then_some((t0, t1))
}
