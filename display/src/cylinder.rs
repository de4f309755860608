//! Cylindrical impostors on the GPU: the fragment-shader twin of the CPU renderers of
//! `altrep::cylinder` at one sub-sample per pixel (`supersample = 1`):
//!
//! * [`CylinderMode::Bounded`] — `MarchBounds::render`: the exact inverse warp, marching only
//!   the range of sectors the stored per-cell bounds allow (what the pipeline's cylinder asset
//!   holds: the texture and the bounds);
//! * [`CylinderMode::Fitted`] — `OffsetTexture::render` with `OffsetMode::Plain`: the fitted
//!   offset from the trilinear 3D texture (one fetch, eight node reads in the shader), the
//!   silhouette mask, the validation (the named point must project within the tolerance);
//! * [`CylinderMode::Hybrid`] — the same with `OffsetMode::Hybrid { steps: m }`: at most `m`
//!   exact sector tests with Newton jumps from the named sector, then the plain result.
//!
//! The offsets are an [`OffsetTexture`] the library fitted; this module fits nothing. The
//! shader (`cylinder.wgsl`) repeats the CPU's formulas in the same order; per-draw tables of
//! `O(L + W + H)` values (sines and cosines of `α − β_c`, each screen column's abscissa and ray
//! sectors, each screen row's slice weights, mask interval and fetch weights) are computed here
//! in `f64` as the CPU computes them. It runs in `f32` ([`Precision::F32`]) or, with
//! `SHADER_F64`, in `f64` ([`Precision::F64`]), where it is the CPU's computation operation for
//! operation. Per-fragment sector tests go to a storage buffer ([`DrawnFrame::steps`], first slot;
//! the second slot is 0: one march per fragment).

use std::f64::consts::TAU;
use std::time::Instant;

use altrep::cylinder::asset::CylinderData;
use altrep::cylinder::frame::{angular_pitch, ray_sectors, row_coordinate};
use altrep::cylinder::{
    CylinderRenderParams, CylindricalTexture, MarchBounds, OffsetMode, OffsetTexture,
};
use altrep::fit::axis_weight;
use altrep_data_gen::{Light, PixelGrid, Supersample};

use crate::offscreen::{self, Pipeline, storage};
use crate::parallax::reals;
use crate::shader::{Precision, Shader};
use crate::{DisplayError, DrawnFrame, Gpu, invalid};

/// How each fragment finds its surface point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CylinderMode {
    /// The exact march within the stored per-cell bounds (`MarchBounds::render`).
    Bounded,
    /// One fetch of the fitted offset, validated (`OffsetMode::Plain`). Needs offsets.
    Fitted,
    /// The fetch refined by at most `steps` sector tests (`OffsetMode::Hybrid`). Needs offsets.
    Hybrid {
        /// Largest number of sector tests `m` (1..=64).
        steps: u32,
    },
}

impl CylinderMode {
    /// `bounded`, `fitted` or `hybrid-m<m>` (the CPU evaluation's names).
    pub fn name(&self) -> String {
        match self {
            Self::Bounded => "bounded".into(),
            Self::Fitted => "fitted".into(),
            Self::Hybrid { steps } => format!("hybrid-m{steps}"),
        }
    }
}

/// What to draw.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CylinderDraw {
    /// Camera azimuth `α` (radians, any finite value): the view looks along `−d(α)`.
    pub alpha: f64,
    /// Screen columns (the quad `[−R, R]` fills them).
    pub width: usize,
    /// Screen rows (the quad `[0, H]`).
    pub height: usize,
    /// Which renderer.
    pub mode: CylinderMode,
    /// Validation tolerance of the fitted modes, output pixels (the CPU evaluation uses 1).
    pub tolerance_px: f64,
    /// The light.
    pub light: Light,
}

/// The fitted offsets as uploaded: nodes, clamp range, mask.
struct Offsets {
    texture: OffsetTexture,
}

/// A cylindrical texture (with its march bounds and optionally fitted offsets) uploaded to the
/// GPU, with the pipeline that draws it.
pub struct CylinderDisplay {
    precision: Precision,
    pipeline: std::sync::Arc<Pipeline>,
    texture: CylindricalTexture,
    bounds: MarchBounds,
    offsets: Option<Offsets>,
    texels: wgpu::Buffer,
}

impl CylinderDisplay {
    /// Uploads the texture of `data` (8 floats per texel), keeps its bounds and, when given, the
    /// fitted `offsets` (which must have been fitted on a texture of the same size), and builds
    /// the pipeline in `precision`. Cost: one pass over the texels; GPU memory `32·L·Ly` bytes
    /// plus per draw the bound codes and the offset nodes.
    ///
    /// Errors: [`Precision::F64`] without `SHADER_F64`; offsets of another texture size; a
    /// shader or pipeline the device rejects ([`DisplayError::Gpu`]).
    pub fn new(
        gpu: &Gpu,
        data: &CylinderData,
        offsets: Option<&OffsetTexture>,
        precision: Precision,
    ) -> Result<Self, DisplayError> {
        let pipeline = offscreen::pipeline(gpu, Shader::Cylinder, precision)?;
        let t = &data.texture;
        if let Some(o) = offsets {
            // The library's own size check (a one-pixel render refuses a texture of another
            // size than the one the offsets were fitted on).
            let one = CylinderRenderParams {
                width: 1,
                height: 1,
                supersample: Supersample::ONE,
                ..CylinderRenderParams::default()
            };
            o.render(t, OffsetMode::Plain, 1.0, &one).map_err(|e| {
                DisplayError::InvalidParameter {
                    name: "offsets",
                    value: e.to_string(),
                    reason: "must be fitted on this texture",
                }
            })?;
        }
        let mut tex = Vec::with_capacity(t.columns() * t.rows() * 8);
        for texel in t.texels() {
            match texel {
                Some(x) => tex.extend_from_slice(&[
                    x.albedo.x, x.albedo.y, x.albedo.z, x.radius, x.normal.x, x.normal.y,
                    x.normal.z, 1.0,
                ]),
                None => tex.extend_from_slice(&[0.0; 8]),
            }
        }
        let texels = storage(gpu, "cylinder texels", bytemuck::cast_slice(&tex));
        Ok(Self {
            precision,
            pipeline,
            texture: t.clone(),
            bounds: data.bounds.clone(),
            offsets: offsets.map(|o| Offsets { texture: o.clone() }),
            texels,
        })
    }

    /// The precision the shader runs in.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// Whether fitted offsets were uploaded (the fitted and hybrid modes need them).
    pub fn has_offsets(&self) -> bool {
        self.offsets.is_some()
    }

    /// Draws one frame and reads back the image, the depth and the per-fragment sector tests
    /// (first slot of [`DrawnFrame::steps`]). Cost: the host tables (`O(L + W + H)`), one draw of
    /// `width × height` fragments, the read-back.
    ///
    /// Errors: a non-finite angle or light, a zero or huge screen, a fitted mode without
    /// offsets, `m` outside `1..=64`, a negative or NaN tolerance, a GPU error.
    pub fn render(&self, gpu: &Gpu, d: &CylinderDraw) -> Result<DrawnFrame, DisplayError> {
        if !d.alpha.is_finite() {
            return Err(invalid("alpha", d.alpha, "must be finite"));
        }
        if d.width == 0 || d.height == 0 || d.width > 8192 || d.height > 8192 {
            return Err(invalid(
                "screen size",
                format!("{}×{}", d.width, d.height),
                "must be in 1..=8192",
            ));
        }
        let dir = d.light.direction;
        if !(dir.is_finite() && d.light.ambient.is_finite()) {
            return Err(invalid("light", format!("{:?}", d.light), "must be finite"));
        }
        let (mode_id, m) = match d.mode {
            CylinderMode::Bounded => (0, 0),
            CylinderMode::Fitted => (1, 0),
            CylinderMode::Hybrid { steps } => {
                if !(1..=64).contains(&steps) {
                    return Err(invalid("hybrid steps", steps, "must be in 1..=64"));
                }
                (2, steps as i32)
            }
        };
        let offsets = match (d.mode, &self.offsets) {
            (CylinderMode::Bounded, _) => None,
            (_, Some(o)) => Some(&o.texture),
            (mode, None) => {
                return Err(invalid(
                    "mode",
                    mode.name(),
                    "needs fitted offsets (CylinderDisplay::new with an OffsetTexture)",
                ));
            }
        };
        if offsets.is_some() && (d.tolerance_px.is_nan() || d.tolerance_px < 0.0) {
            return Err(invalid("tolerance_px", d.tolerance_px, "must be ≥ 0"));
        }
        let t0 = Instant::now();
        let tex = &self.texture;
        let (l, rows) = (tex.columns(), tex.rows());
        let da = angular_pitch(l);
        // The shader wraps columns by whole turns, at most 64: angles past 60 turns are reduced
        // modulo 2π here first (the CPU's rounding of such angles then differs slightly).
        let alpha = if (d.alpha / da).abs() > 60.0 * l as f64 {
            d.alpha.rem_euclid(TAU)
        } else {
            d.alpha
        };
        let grid = PixelGrid {
            width: d.width,
            height: d.height,
            cylinder: tex.cylinder(),
        };
        let radius = grid.cylinder.radius;
        // The CPU's sub-sample positions at supersample 1 (render_rows).
        let xs: Vec<f64> = (0..d.width)
            .map(|i| grid.x_at(i as f64 + 0.5) / radius)
            .collect();
        let vs: Vec<f64> = (0..d.height)
            .map(|j| row_coordinate(grid.y_at(j as f64 + 0.5), &grid.cylinder, rows))
            .collect();
        let [bx, ry, ba] = self.bounds.cells();
        let li = l as i64;

        // Integer and real scalars, then the tables (offsets recorded in the scalars).
        let mut ints = vec![0i32; 22];
        let mut rs = vec![0f64; 6];
        let put_i = |ints: &mut Vec<i32>, slot: usize, v: i64| ints[slot] = v as i32;
        // Per texture column: sin, cos of α − β_c (SliceView::new).
        let off_trig = rs.len();
        for c in 0..l {
            let beta = c as f64 * da;
            rs.push((alpha - beta).sin());
            rs.push((alpha - beta).cos());
        }
        let off_colx = rs.len();
        rs.extend_from_slice(&xs);
        // Per screen column: the ray's sectors, the bounds' frame and cell, the code base.
        let off_coli = ints.len();
        let mut angle_cell = 0i64;
        for &x in &xs {
            let r = ray_sectors(x, alpha, l);
            let guess = ((alpha.rem_euclid(TAU) - x.asin()) / da).floor() as i64;
            let first_b = r.first - li * (r.first - guess + li / 2).div_euclid(li);
            let (cell_i, base) = match self.bounds.cell(x, 0.0, alpha) {
                Some(c) => {
                    let (i, a) = (c % bx, c / (bx * ry));
                    angle_cell = a as i64;
                    // MarchBounds::start: code q stands for sector q + base.
                    let a_ref = ((a as f64 * TAU / ba as f64) / da).floor() as i64;
                    let base = if i >= bx / 2 {
                        a_ref - li / 2 - 4
                    } else {
                        a_ref - 3
                    };
                    (i as i64, base)
                }
                None => (0, 0),
            };
            for v in [r.first, r.step, r.count as i64, first_b, cell_i, base] {
                ints.push(v as i32);
            }
        }
        // Per screen row: the slice, the bound row cell, the mask and the fetch's y weights.
        let off_rowi = ints.len();
        let off_rowr = rs.len();
        let last = rows - 1;
        for &v in &vs {
            let vc = if v.is_nan() {
                0.0
            } else {
                v.clamp(0.0, last as f64)
            };
            let j = (vc.floor() as usize).min(last);
            let t = (vc - j as f64) as f32;
            let rcell = self.bounds.cell(0.0, v, alpha).map_or(0, |c| (c / bx) % ry) as i64;
            let (mut ok, mut lo, mut hi, mut y0, mut y1, mut ty) = (0, 0.0, 0.0, 0, 0, 0.0);
            if let Some(o) = offsets {
                let interval = match o.mask() {
                    Some(mask) => mask.interval(v, alpha),
                    None => Some((-1.0, 1.0)),
                };
                if let Some((a, b)) = interval {
                    (ok, lo, hi) = (1, a, b);
                }
                let g = o.grid();
                let w = axis_weight((v + 0.5) / rows as f64, g.cells()[1], g.periodic()[1]);
                (y0, y1, ty) = (w.0 as i64, w.1 as i64, w.2);
            }
            for v in [j as i64, i64::from(t.to_bits()), rcell, ok, y0, y1] {
                ints.push(v as i32);
            }
            rs.extend_from_slice(&[lo, hi, ty]);
        }
        let off_grid = rs.len();
        if let Some(o) = offsets {
            let g = o.grid();
            let [nx, ny, _] = g.nodes();
            let cells = g.cells();
            let wz = axis_weight((alpha / TAU).rem_euclid(1.0), cells[2], g.periodic()[2]);
            put_i(&mut ints, 8, i64::from(o.mask().is_some()));
            put_i(&mut ints, 9, nx as i64);
            put_i(&mut ints, 10, ny as i64);
            put_i(&mut ints, 11, cells[0] as i64);
            put_i(&mut ints, 12, wz.0 as i64);
            put_i(&mut ints, 13, wz.1 as i64);
            let data = &o.report.fit.data;
            rs[1] = d.tolerance_px * 2.0 / d.width as f64;
            rs[2] = data.min;
            rs[3] = data.max;
            rs[4] = wz.2;
            rs.extend_from_slice(g.values());
        }
        // The bound codes.
        let off_start = ints.len();
        ints.extend(self.bounds.start().iter().map(|&c| i32::from(c)));
        let off_stop = ints.len();
        ints.extend(self.bounds.stop().iter().map(|&c| i32::from(c)));
        rs[0] = alpha / da;
        rs[5] = l as f64;
        for (slot, v) in [
            (0, l as i64),
            (1, rows as i64),
            (2, d.width as i64),
            (3, mode_id),
            (4, i64::from(m)),
            (5, bx as i64),
            (6, ry as i64),
            (7, angle_cell),
            (14, off_trig as i64),
            (15, off_colx as i64),
            (16, off_rowr as i64),
            (17, off_grid as i64),
            (18, off_coli as i64),
            (19, off_rowi as i64),
            (20, off_start as i64),
            (21, off_stop as i64),
        ] {
            put_i(&mut ints, slot, v);
        }
        let rbuf = storage(gpu, "cylinder reals", &reals(&rs, self.precision));
        let ibuf = storage(gpu, "cylinder ints", bytemuck::cast_slice(&ints));
        let light = [dir.x, dir.y, dir.z, d.light.ambient];
        let lbuf = storage(gpu, "light", bytemuck::cast_slice(&light));
        let frags = d.width * d.height;
        let drawn = offscreen::draw(
            gpu,
            &self.pipeline,
            &[&rbuf, &ibuf, &self.texels, &lbuf],
            frags,
            (d.width, d.height),
            t0,
        )?;
        Ok(DrawnFrame {
            image: drawn.image,
            steps: drawn.steps.into_iter().map(|s| [s, 0]).collect(),
            depth: drawn.depth,
            millis: drawn.millis,
        })
    }
}
