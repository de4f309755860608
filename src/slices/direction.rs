//! Direction choice by measured error (docs/design.md §9.6).
//!
//! The direction rule of Meyer & Neyret ([`super::choose_direction`]) picks the axis most
//! aligned with the view, and the criterion then picks that axis's merge level. It ignores what
//! the level does to the error: at 20° from the normal, seen from 4 voxels per pixel, the `y`
//! stack of the fur tile is drawn at 4 slices (27.0 dB) while the `x` stack, at the 32 slices
//! its criterion asks, gives 39.8 dB. The rule's choice can fall 13 dB below the best direction.
//!
//! A [`DirectionTable`] measures instead: at every node of a grid of view directions (polar and
//! azimuth angles, `StackView` conventions) and pixel sizes, the PSNR of every built stack
//! (axis, level) against the ray-marched truth. A view then takes, among the built axes, the one
//! whose stack at *its* criterion level has the highest PSNR interpolated from the nodes
//! (multilinear in polar angle, azimuth — periodic — and `log2` of the pixel size). The level
//! stays the criterion's: the table changes which direction is drawn, never how many slices.
//!
//! Interpolating per level, not per axis, keeps the jumps of the criterion's level exact: between
//! two nodes the error of one stack varies smoothly, while the level the criterion picks jumps.
//!
//! Cost: one truth march per node and pixel size, and one slice render per built stack and
//! level there ([`DirectionTable::measure`]); a query reads at most 8 nodes per axis.

use rayon::prelude::*;

use super::measure::capped;
use super::merge::SliceData;
use super::object::{stored_axes, stored_level};
use super::render::{SliceRenderParams, StackView, render_slices};
use super::stack::{Axis, ViewChoice};
use super::truth::{VolumeTruthParams, render_truth};
use super::{SliceError, TexelVolume};
use crate::metrics::psnr;

/// The nodes of a [`DirectionTable`]: polar angles (degrees from `+y`, ascending, each at least
/// 1° from the surface plane), azimuths (degrees, ascending, within one turn; periodic) and
/// pixel sizes (voxels per pixel, ascending, positive).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionGrid {
    /// Polar angles (degrees, ascending, in `[0, 180]`, none within 1° of 90°).
    pub polar_deg: Vec<f64>,
    /// Azimuths (degrees, ascending, spanning less than 360°).
    pub azimuth_deg: Vec<f64>,
    /// Pixel sizes in voxels (ascending, > 0).
    pub pixel_voxels: Vec<f64>,
}

impl DirectionGrid {
    /// Errors: an empty or unsorted list, a polar angle outside `[0, 180]` or within 1° of the
    /// surface plane, azimuths spanning a turn or more, a non-positive pixel size.
    pub fn validate(&self) -> Result<(), SliceError> {
        for (list, what) in [
            (&self.polar_deg, "direction table polar angles"),
            (&self.azimuth_deg, "direction table azimuths"),
            (&self.pixel_voxels, "direction table pixel sizes"),
        ] {
            if list.is_empty() {
                return Err(SliceError::ZeroSize { what });
            }
            if list.iter().any(|x| !x.is_finite()) || list.windows(2).any(|w| w[1] <= w[0]) {
                return Err(SliceError::InvalidParameter {
                    name: what,
                    value: format!("{list:?}"),
                    reason: "must be finite and strictly ascending",
                });
            }
        }
        for &p in &self.polar_deg {
            StackView::degrees(p, 0.0).validate()?;
            super::check_range(
                "direction table polar angle",
                p,
                0.0,
                180.0,
                "in [0°, 180°]",
            )?;
        }
        let span = self.azimuth_deg[self.azimuth_deg.len() - 1] - self.azimuth_deg[0];
        if span >= 360.0 {
            return Err(SliceError::InvalidParameter {
                name: "direction table azimuths",
                value: format!("{:?}", self.azimuth_deg),
                reason: "must span less than one turn (they repeat every 360°)",
            });
        }
        for &p in &self.pixel_voxels {
            super::check_range(
                "direction table pixel size",
                p,
                1e-3,
                64.0,
                "in [0.001, 64] voxels",
            )?;
        }
        Ok(())
    }

    fn nodes(&self) -> usize {
        self.polar_deg.len() * self.azimuth_deg.len() * self.pixel_voxels.len()
    }
}

/// Measured PSNR of every built stack at the nodes of a [`DirectionGrid`], and the direction
/// choice it supports (see the module docs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DirectionTable {
    grid: DirectionGrid,
    /// Visible depth of the criterion in pixels.
    d_pixels: f64,
    /// Voxels along each axis.
    dims: [usize; 3],
    /// Voxel size (world units).
    voxel: f64,
    /// Levels per axis (`log2 N + 1`).
    levels: usize,
    /// `psnr[((node · 3) + axis) · levels + level]`, node `(pixel · P + polar) · A + azimuth`;
    /// `None` for a stack not built.
    psnr: Vec<Option<f64>>,
}

impl DirectionTable {
    /// Measures the table of `data` (cut from `volume`): at each node the truth image and every
    /// built stack's image; `render(pixel size)` gives the parameters of the slices' image and of
    /// the truth's (the same window; the truth usually with more rays per pixel). `d_pixels` is the criterion's
    /// visible depth in pixels (the depth of a view is `d_pixels · p · voxel size`). Cost: one
    /// truth march and one render per built stack per node (nodes in parallel).
    ///
    /// Errors: an invalid grid or `d_pixels`, slice data not cut from a volume of this size,
    /// invalid render or truth parameters.
    pub fn measure(
        volume: &TexelVolume,
        data: &SliceData,
        grid: &DirectionGrid,
        d_pixels: f64,
        render: &(dyn Fn(f64) -> (SliceRenderParams, SliceRenderParams) + Sync),
        truth: &VolumeTruthParams,
    ) -> Result<Self, SliceError> {
        grid.validate()?;
        super::check_range("d (pixels)", d_pixels, 1e-3, 1e3, "in [0.001, 1000]")?;
        super::measure::check_cut_from(data, volume)?;
        let dims = volume.dims();
        let levels = level_count(dims);
        let (a_n, p_n) = (grid.azimuth_deg.len(), grid.polar_deg.len());
        let per_node: Vec<Vec<Option<f64>>> = (0..grid.nodes())
            .into_par_iter()
            .map(|node| {
                let ai = node % a_n;
                let pi = (node / a_n) % p_n;
                let di = node / (a_n * p_n);
                let view = StackView::degrees(grid.polar_deg[pi], grid.azimuth_deg[ai]);
                let (rp, fine) = render(grid.pixel_voxels[di]);
                let reference = render_truth(volume, &view, &fine, truth)?;
                let mut out = vec![None; 3 * levels];
                for axis in Axis::ALL {
                    for level in 0..levels {
                        if data.stack(axis, level).is_err() {
                            continue;
                        }
                        let img = render_slices(data, axis, level, &view, &rp)?;
                        out[axis.index() * levels + level] = Some(capped(psnr(&img, &reference)?));
                    }
                }
                Ok(out)
            })
            .collect::<Result<_, SliceError>>()?;
        Ok(Self {
            grid: grid.clone(),
            d_pixels,
            dims,
            voxel: volume.voxel_size(),
            levels,
            psnr: per_node.into_iter().flatten().collect(),
        })
    }

    /// The grid the table was measured on.
    pub fn grid(&self) -> &DirectionGrid {
        &self.grid
    }

    /// Voxels along each axis of the volume the table was measured on.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Checks a table read from a file: a valid grid and depth, voxels a power of two per axis,
    /// one finite PSNR or none per node, axis and level. Errors name what is wrong.
    pub fn check(&self) -> Result<(), SliceError> {
        self.grid.validate()?;
        super::check_range("d (pixels)", self.d_pixels, 1e-3, 1e3, "in [0.001, 1000]")?;
        super::check_range("voxel size", self.voxel, f64::MIN_POSITIVE, f64::MAX, "> 0")?;
        let levels = level_count(self.dims);
        if self.dims.iter().any(|n| !n.is_power_of_two()) || self.levels != levels {
            return Err(SliceError::InvalidParameter {
                name: "direction table dims",
                value: format!("{:?} with {} levels", self.dims, self.levels),
                reason: "must be powers of two with log2 N + 1 levels",
            });
        }
        let want = self.grid.nodes() * 3 * self.levels;
        if self.psnr.len() != want || self.psnr.iter().flatten().any(|e| !e.is_finite()) {
            return Err(SliceError::InvalidParameter {
                name: "direction table PSNR",
                value: format!("{} entries", self.psnr.len()),
                reason: "must hold one finite value or null per node, axis and level",
            });
        }
        Ok(())
    }

    /// PSNR (dB) of the stack `(axis, level)` seen along `view` at `pixel_voxels` voxels per
    /// pixel, interpolated from the nodes: multilinear in polar angle and azimuth (clamped to the
    /// polar range, periodic in azimuth) and in `log2` of the pixel size (clamped). Nodes where
    /// the stack was not built are left out and the weights renormalised; `None` when no node
    /// has it.
    pub fn predict(
        &self,
        axis: Axis,
        level: usize,
        view: &StackView,
        pixel_voxels: f64,
    ) -> Option<f64> {
        if level >= self.levels || !pixel_voxels.is_finite() || pixel_voxels <= 0.0 {
            return None;
        }
        let polar = bracket(&self.grid.polar_deg, view.polar.to_degrees());
        let azimuth = bracket_periodic(&self.grid.azimuth_deg, view.azimuth.to_degrees());
        let logs: Vec<f64> = self.grid.pixel_voxels.iter().map(|p| p.log2()).collect();
        let pixel = bracket(&logs, pixel_voxels.log2());
        let (a_n, p_n) = (self.grid.azimuth_deg.len(), self.grid.polar_deg.len());
        let (mut sum, mut weight) = (0.0, 0.0);
        for (di, wd) in pixel {
            for (pi, wp) in polar {
                for (ai, wa) in azimuth {
                    let w = wd * wp * wa;
                    if w <= 0.0 {
                        continue;
                    }
                    let node = (di * p_n + pi) * a_n + ai;
                    if let Some(e) = self.psnr[(node * 3 + axis.index()) * self.levels + level] {
                        sum += w * e;
                        weight += w;
                    }
                }
            }
        }
        (weight > 0.0).then(|| sum / weight)
    }

    /// The stack `data` draws for `view` at `pixel_voxels` voxels per pixel: among the axes
    /// `data` holds (and `allowed`), the one whose stack at the criterion's level (or the stored
    /// level [`super::choose_stored`] falls back to) has the highest predicted PSNR. Ties go to
    /// the direction rule's order `Y, X, Z`. Where the table predicts nothing for any axis, the
    /// direction rule decides ([`super::choose_stored`]).
    ///
    /// Errors: an invalid view or pixel size, slice data of another size than the table's, no
    /// allowed axis stored.
    pub fn choose(
        &self,
        data: &SliceData,
        view: &StackView,
        pixel_voxels: f64,
        allowed: [bool; 3],
    ) -> Result<ViewChoice, SliceError> {
        view.validate()?;
        super::check_range(
            "pixel size",
            pixel_voxels,
            1e-3,
            64.0,
            "in [0.001, 64] voxels",
        )?;
        if data.dims() != self.dims {
            return Err(SliceError::InvalidParameter {
                name: "slice data",
                value: format!("{:?} vs table {:?}", data.dims(), self.dims),
                reason: "must be the slices the table was measured on",
            });
        }
        let stored = stored_axes(data);
        let allowed = [0, 1, 2].map(|i| allowed[i] && stored[i]);
        if !allowed.contains(&true) {
            return Err(SliceError::InvalidParameter {
                name: "allowed axes",
                value: format!("{allowed:?}"),
                reason: "at least one allowed axis must be stored",
            });
        }
        let depth = self.d_pixels * pixel_voxels * self.voxel;
        let v = view.vector();
        let mut best: Option<(ViewChoice, f64)> = None;
        for axis in [Axis::Y, Axis::X, Axis::Z] {
            if !allowed[axis.index()] {
                continue;
            }
            let c = stored_level(data, axis, v, depth)?;
            let Some(e) = self.predict(axis, c.level, view, pixel_voxels) else {
                continue;
            };
            if best.is_none_or(|(_, b)| e > b) {
                best = Some((c, e));
            }
        }
        match best {
            Some((c, _)) => Ok(c),
            None => {
                let s = data.voxel_size();
                let axis = super::choose_direction(v, [s; 3], allowed)?;
                stored_level(data, axis, v, depth)
            }
        }
    }
}

/// Merge levels of the longest axis of a volume of `dims` voxels (`log2 N + 1`).
fn level_count(dims: [usize; 3]) -> usize {
    dims.iter()
        .map(|n| n.trailing_zeros() as usize + 1)
        .max()
        .unwrap_or(1)
}

/// The two nodes around `x` in the ascending `nodes` and their linear weights (clamped at the
/// ends; a single node has weight 1).
fn bracket(nodes: &[f64], x: f64) -> [(usize, f64); 2] {
    let last = nodes.len() - 1;
    if x <= nodes[0] {
        return [(0, 1.0), (0, 0.0)];
    }
    if x >= nodes[last] {
        return [(last, 1.0), (last, 0.0)];
    }
    let hi = nodes.partition_point(|&n| n <= x).min(last);
    let lo = hi - 1;
    let t = (x - nodes[lo]) / (nodes[hi] - nodes[lo]);
    [(lo, 1.0 - t), (hi, t)]
}

/// [`bracket`] for angles in degrees repeating every 360°.
fn bracket_periodic(nodes: &[f64], x: f64) -> [(usize, f64); 2] {
    let last = nodes.len() - 1;
    if last == 0 {
        return [(0, 1.0), (0, 0.0)];
    }
    // x in [nodes[0], nodes[0] + 360).
    let x = nodes[0] + (x - nodes[0]).rem_euclid(360.0);
    if x >= nodes[last] {
        let span = nodes[0] + 360.0 - nodes[last];
        let t = (x - nodes[last]) / span;
        return [(last, 1.0 - t), (0, t)];
    }
    bracket(nodes, x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn brackets_weigh_linearly_and_clamp() {
        let n = [0.0, 10.0, 30.0];
        assert_eq!(bracket(&n, -5.0), [(0, 1.0), (0, 0.0)]);
        assert_eq!(bracket(&n, 40.0), [(2, 1.0), (2, 0.0)]);
        let [(a, wa), (b, wb)] = bracket(&n, 15.0);
        assert_eq!((a, b), (1, 2));
        assert_relative_eq!(wa, 0.75, epsilon = 1e-12);
        assert_relative_eq!(wb, 0.25, epsilon = 1e-12);
        let [(a, wa), (b, wb)] = bracket(&n, 10.0);
        assert_eq!((a, b), (1, 2));
        assert_relative_eq!(wa, 1.0, epsilon = 1e-12);
        assert_relative_eq!(wb, 0.0, epsilon = 1e-12);
    }

    #[test]
    fn azimuths_wrap_around_the_turn() {
        let n = [0.0, 60.0, 180.0, 240.0];
        // 300° lies between 240° and 360° (= 0°).
        let [(a, wa), (b, wb)] = bracket_periodic(&n, 300.0);
        assert_eq!((a, b), (3, 0));
        assert_relative_eq!(wa, 0.5, epsilon = 1e-12);
        assert_relative_eq!(wb, 0.5, epsilon = 1e-12);
        // −30° is 330°.
        let [(a, wa), (b, wb)] = bracket_periodic(&n, -30.0);
        assert_eq!((a, b), (3, 0));
        assert_relative_eq!(wa, 0.25, epsilon = 1e-12);
        assert_relative_eq!(wb, 0.75, epsilon = 1e-12);
        assert_eq!(bracket_periodic(&[45.0], 200.0), [(0, 1.0), (0, 0.0)]);
    }

    /// A table read back whole passes its check; one with a PSNR missing, or a non-finite one,
    /// or a grid out of order, is refused naming what is wrong.
    #[test]
    fn damaged_tables_are_refused() {
        use crate::slices::{SliceParams, TestTile, build_slices, test_tile};
        let vol = test_tile(TestTile::Grass, 4, 1).unwrap();
        let (data, _) = build_slices(&vol, &SliceParams::default()).unwrap();
        let grid = DirectionGrid {
            polar_deg: vec![0.0, 60.0],
            azimuth_deg: vec![0.0],
            pixel_voxels: vec![1.0],
        };
        let rp = SliceRenderParams {
            width: 6,
            height: 6,
            ..SliceRenderParams::default()
        };
        let render = |_: f64| (rp.clone(), rp.clone());
        let truth = VolumeTruthParams {
            steps_per_voxel: 2,
            ..VolumeTruthParams::default()
        };
        let table = DirectionTable::measure(&vol, &data, &grid, 1.0, &render, &truth).unwrap();
        let json = serde_json::to_value(&table).unwrap();
        let back: DirectionTable = serde_json::from_value(json.clone()).unwrap();
        assert_eq!(back, table);
        assert!(back.check().is_ok());
        let damaged = |f: &dyn Fn(&mut serde_json::Value)| {
            let mut j = json.clone();
            f(&mut j);
            let t: DirectionTable = serde_json::from_value(j).unwrap();
            t.check().unwrap_err().to_string()
        };
        let e = damaged(&|j| {
            j["psnr"].as_array_mut().unwrap().pop();
        });
        assert!(e.contains("direction table PSNR"), "{e}");
        let e = damaged(&|j| j["grid"]["polar_deg"] = serde_json::json!([60.0, 0.0]));
        assert!(e.contains("polar"), "{e}");
        let e = damaged(&|j| j["levels"] = serde_json::json!(7));
        assert!(e.contains("dims"), "{e}");
    }

    #[test]
    fn bad_grids_are_named() {
        let ok = DirectionGrid {
            polar_deg: vec![0.0, 45.0],
            azimuth_deg: vec![0.0],
            pixel_voxels: vec![1.0],
        };
        assert!(ok.validate().is_ok());
        for bad in [
            DirectionGrid {
                polar_deg: vec![],
                ..ok.clone()
            },
            DirectionGrid {
                polar_deg: vec![45.0, 0.0],
                ..ok.clone()
            },
            DirectionGrid {
                polar_deg: vec![0.0, 90.0],
                ..ok.clone()
            },
            DirectionGrid {
                azimuth_deg: vec![0.0, 360.0],
                ..ok.clone()
            },
            DirectionGrid {
                pixel_voxels: vec![0.0],
                ..ok.clone()
            },
            DirectionGrid {
                pixel_voxels: vec![f64::NAN],
                ..ok.clone()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
    }
}
