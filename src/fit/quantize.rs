//! Affine quantisation of node values to `b` bits, and the fit error after it.
//!
//! A stored code `q ∈ {0, …, 2ᵇ − 1}` stands for `offset + scale·q` (an UNORM texture times a
//! scale plus a bias in the shader). Codes are chosen by rounding with the min/max mapping
//! (`offset = min`, `scale = (max − min)/(2ᵇ − 1)`, error ≤ `scale/2` per node); then `scale`
//! and `offset` are re-fitted by least squares against the samples. Because trilinear weights
//! sum to 1, `g_q = offset + scale·G(q)` with `G` the interpolant of the raw codes, so the
//! refit is a linear regression of `d` on `G(q)`: never worse (in RMS) than the min/max mapping.

use rayon::prelude::*;

use super::grid::{FitSamples, TrilinearGrid};
use super::{ErrorStats, FitError, error_stats};

/// Node values quantised to `bits` bits.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Quantized {
    /// Bits per code, 1 to 16.
    pub bits: u32,
    /// Value of one code step.
    pub scale: f64,
    /// Value of code 0.
    pub offset: f64,
    /// One code per node, same order as [`TrilinearGrid::values`].
    pub codes: Vec<u16>,
}

impl Quantized {
    /// The min/max affine quantisation of `grid`'s node values. Errors: `bits ∉ 1..=16`.
    /// Cost: O(nodes).
    pub fn min_max(grid: &TrilinearGrid, bits: u32) -> Result<Self, FitError> {
        if !(1..=16).contains(&bits) {
            return Err(FitError::InvalidParameter {
                name: "bits",
                value: bits.to_string(),
                reason: "quantisation uses 1 to 16 bits",
            });
        }
        let levels = ((1u32 << bits) - 1) as f64;
        let (lo, hi) = grid.value_range();
        let scale = if hi > lo { (hi - lo) / levels } else { 0.0 };
        let codes = grid
            .values()
            .iter()
            .map(|&v| {
                if scale > 0.0 {
                    ((v - lo) / scale).round().clamp(0.0, levels) as u16
                } else {
                    0
                }
            })
            .collect();
        Ok(Self {
            bits,
            scale,
            offset: lo,
            codes,
        })
    }

    /// The dequantised grid (`offset + scale·code` per node) with `template`'s layout.
    pub fn to_grid(&self, template: &TrilinearGrid) -> Result<TrilinearGrid, FitError> {
        TrilinearGrid::new(
            template.cells(),
            template.periodic(),
            self.codes
                .iter()
                .map(|&q| self.offset + self.scale * q as f64)
                .collect(),
        )
    }

    /// Re-fits `scale` and `offset` by least squares on the defined samples, codes fixed
    /// (see the module docs). Cost: one parallel pass over the samples.
    pub fn refit(
        &mut self,
        template: &TrilinearGrid,
        samples: &FitSamples,
    ) -> Result<(), FitError> {
        let raw = TrilinearGrid::new(
            template.cells(),
            template.periodic(),
            self.codes.iter().map(|&q| q as f64).collect(),
        )?;
        let [nx, ny, _] = samples.dims();
        let w = super::grid::sample_weights(samples, raw.cells(), raw.periodic());
        // Σ1, ΣG, Σd, ΣG², ΣGd over defined samples.
        let sums = samples
            .values()
            .par_chunks(nx * ny)
            .enumerate()
            .map(|(k, slice)| {
                let mut s = [0.0f64; 5];
                for (j, row) in slice.chunks_exact(nx).enumerate() {
                    for (i, v) in row.iter().enumerate() {
                        if let Some(d) = v {
                            let g = raw.blend([w[0][i], w[1][j], w[2][k]]);
                            s[0] += 1.0;
                            s[1] += g;
                            s[2] += d;
                            s[3] += g * g;
                            s[4] += g * d;
                        }
                    }
                }
                s
            })
            .reduce(
                || [0.0; 5],
                |a, b| {
                    [
                        a[0] + b[0],
                        a[1] + b[1],
                        a[2] + b[2],
                        a[3] + b[3],
                        a[4] + b[4],
                    ]
                },
            );
        let n = sums[0];
        if n == 0.0 {
            return Err(FitError::NoDefinedSample);
        }
        let (mg, md) = (sums[1] / n, sums[2] / n);
        let var = sums[3] / n - mg * mg;
        let cov = sums[4] / n - mg * md;
        if var > 1e-12 * (sums[3] / n).max(1e-300) {
            self.scale = cov / var;
            self.offset = md - self.scale * mg;
        } else {
            // All fetched codes equal: only the offset matters.
            self.offset = md - self.scale * mg;
        }
        Ok(())
    }
}

/// The best affine `bits`-bit quantisation of `grid` for `samples` and the fit error after it.
/// Cost: two parallel passes over the samples.
pub fn quantize(
    grid: &TrilinearGrid,
    samples: &FitSamples,
    bits: u32,
) -> Result<(Quantized, ErrorStats), FitError> {
    let mut q = Quantized::min_max(grid, bits)?;
    q.refit(grid, samples)?;
    let stats = error_stats(samples, &q.to_grid(grid)?);
    Ok((q, stats))
}
