//! Quad-tree texture fusion from several registered views (Bornik & Ferko 2002, after Ofek et
//! al.): rebuild a planar texture, rejecting non-modelled occluders by a per-node median.
//!
//! ## Registration
//! The texture is `N × N` texels, `N = 2^L`; quad-tree level `ℓ` has `2^ℓ × 2^ℓ` nodes (level `L`
//! = texels). A [`FusionView`] of scale `m` is an image of `(N/2^m)²` pixels whose pixel `(x, y)`
//! covers texels `[x·2^m, (x+1)·2^m) × [y·2^m, (y+1)·2^m)` — the paper's recursion stops where
//! the projected node matches the pixel, so the view fills level `L − m`.
//!
//! ## Rejection (per node, per level)
//! At a node of level `ℓ`, every view that sees it at resolution `ℓ` or finer gives an estimate
//! (finer views averaged over the node); the per-channel median of these estimates is the
//! reference, and a level-`ℓ` value is kept only if every channel is within `tolerance` of it.
//! Occluders present in a minority of the views are then rejected. Without rejection every value
//! is kept.
//!
//! ## Level fusion (up, differences, down)
//! * Up: `G_L` = mean of the kept values; for `ℓ < L`, `G_ℓ` = mean over the four children, a
//!   child without `G` replaced by the node's own mean of kept values (a node with neither is
//!   empty) — high-resolution data wins where it exists.
//! * Differences: `D_ℓ = G_ℓ − G_{ℓ−1}(parent)` where both exist, else 0.
//! * Down: `F_0 = G_0`, `F_ℓ = F_{ℓ−1}(parent) + D_ℓ`; the result is `F_L`, where every level
//!   holds both high- and low-resolution information.
//!
//! Cost: `O(N² · views)` for estimates and medians, `O(N²)` for the passes.

use rayon::prelude::*;

use super::mip::{MipError, Texture};
use crate::stats::{EvenMedian, median};
use altrep_data_gen::SplitMix64;

/// One registered view (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct FusionView {
    /// The image, `(N/2^scale_log2)²` pixels.
    pub image: Texture,
    /// `m`: one pixel covers `2^m × 2^m` texels.
    pub scale_log2: u32,
}

/// Parameters of [`fuse`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FusionParams {
    /// Apply the median rejection.
    pub reject: bool,
    /// Largest accepted distance to the median, in texel-value units (> 0).
    pub tolerance: f64,
}

impl Default for FusionParams {
    /// Rejection on, tolerance 0.1.
    fn default() -> Self {
        Self {
            reject: true,
            tolerance: 0.1,
        }
    }
}

/// What [`fuse`] did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FusionReport {
    /// View values offered, per level (coarsest first).
    pub offered: Vec<usize>,
    /// View values rejected, per level.
    pub rejected: Vec<usize>,
    /// Fraction of texels whose final value came without any finest-level data.
    pub coarse_only_fraction: f64,
    /// Build time, seconds.
    pub seconds: f64,
}

/// Box average of a `s × s` image (`ch` channels) by `2^k` per axis.
fn reduce(img: &[f64], s: usize, ch: usize, k: u32) -> Vec<f64> {
    let f = 1usize << k;
    let s2 = s / f;
    let mut out = vec![0.0; s2 * s2 * ch];
    out.par_chunks_mut(s2 * ch)
        .enumerate()
        .for_each(|(y, row)| {
            for x in 0..s2 {
                for dy in 0..f {
                    for dx in 0..f {
                        let k = ((y * f + dy) * s + x * f + dx) * ch;
                        for c in 0..ch {
                            row[x * ch + c] += img[k + c];
                        }
                    }
                }
                row[x * ch..(x + 1) * ch]
                    .iter_mut()
                    .for_each(|v| *v /= (f * f) as f64);
            }
        });
    out
}

/// Fuses `views` into an `n × n` texture (`n` a power of two, 1 to 4096). Cost: module docs.
pub fn fuse(
    views: &[FusionView],
    n: usize,
    params: &FusionParams,
) -> Result<(Texture, FusionReport), MipError> {
    let start = std::time::Instant::now();
    if !(n.is_power_of_two() && n <= 4096) {
        return Err(MipError::InvalidParams {
            name: "size",
            reason: "must be a power of two up to 4096",
        });
    }
    if !(params.tolerance.is_finite() && params.tolerance > 0.0) {
        return Err(MipError::InvalidParams {
            name: "tolerance",
            reason: "must be finite and > 0",
        });
    }
    let Some(first) = views.first() else {
        return Err(MipError::InvalidParams {
            name: "views",
            reason: "needs at least one view",
        });
    };
    let ch = first.image.channels;
    let big_l = n.trailing_zeros();
    for v in views {
        let s = n >> v.scale_log2.min(big_l);
        if v.scale_log2 > big_l
            || v.image.width != s
            || v.image.height != s
            || v.image.channels != ch
        {
            return Err(MipError::InvalidParams {
                name: "views",
                reason: "every view must be (n/2^scale)² pixels with the same channel count",
            });
        }
        Texture::new(v.image.width, v.image.height, ch, v.image.data.clone())?;
    }
    let levels = big_l as usize + 1;
    // Per level: sum of kept values, count of kept values.
    let mut sums: Vec<Vec<f64>> = (0..levels)
        .map(|l| vec![0.0; (1 << (2 * l)) * ch])
        .collect();
    let mut counts: Vec<Vec<u32>> = (0..levels).map(|l| vec![0; 1 << (2 * l)]).collect();
    let (mut offered, mut rejected) = (vec![0usize; levels], vec![0usize; levels]);
    let images: Vec<Vec<f64>> = views
        .iter()
        .map(|v| v.image.data.iter().map(|&x| f64::from(x)).collect())
        .collect();
    for l in 0..levels {
        let here: Vec<usize> = (0..views.len())
            .filter(|&k| big_l - views[k].scale_log2 == l as u32)
            .collect();
        if here.is_empty() {
            continue;
        }
        // Estimates at level l from every view at level l or finer.
        let estimates: Vec<Vec<f64>> = (0..views.len())
            .filter(|&k| big_l - views[k].scale_log2 >= l as u32)
            .map(|k| {
                let lk = big_l - views[k].scale_log2;
                reduce(&images[k], 1 << lk, ch, lk - l as u32)
            })
            .collect();
        let nodes = 1usize << (2 * l);
        for node in 0..nodes {
            let med: Vec<f64> = (0..ch)
                .map(|c| {
                    let mut v: Vec<f64> = estimates.iter().map(|e| e[node * ch + c]).collect();
                    // Mean of the two middle estimates for an even count; never empty
                    // (the views of level l are among the estimates).
                    median(&mut v, EvenMedian::Mean).unwrap_or(0.0)
                })
                .collect();
            for &k in &here {
                let val = &images[k][node * ch..(node + 1) * ch];
                offered[l] += 1;
                let keep = !params.reject
                    || val
                        .iter()
                        .zip(&med)
                        .all(|(x, m)| (x - m).abs() <= params.tolerance);
                if keep {
                    counts[l][node] += 1;
                    for c in 0..ch {
                        sums[l][node * ch + c] += val[c];
                    }
                } else {
                    rejected[l] += 1;
                }
            }
        }
    }
    // Up: G_l.
    let mut g: Vec<Vec<Option<Vec<f64>>>> = vec![Vec::new(); levels];
    for l in (0..levels).rev() {
        let side = 1usize << l;
        g[l] = (0..side * side)
            .map(|node| {
                let own = (counts[l][node] > 0).then(|| {
                    (0..ch)
                        .map(|c| sums[l][node * ch + c] / f64::from(counts[l][node]))
                        .collect::<Vec<f64>>()
                });
                if l + 1 == levels {
                    return own;
                }
                let (x, y) = (node % side, node / side);
                let kids = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .map(|(dx, dy)| g[l + 1][(2 * y + dy) * 2 * side + 2 * x + dx].clone());
                if kids.iter().all(Option::is_none) {
                    return own;
                }
                let mut acc = vec![0.0; ch];
                let mut n_used = 0.0;
                for kid in &kids {
                    match (kid, &own) {
                        (Some(k), _) => {
                            acc.iter_mut().zip(k).for_each(|(a, x)| *a += x);
                            n_used += 1.0;
                        }
                        (None, Some(o)) => {
                            acc.iter_mut().zip(o).for_each(|(a, x)| *a += x);
                            n_used += 1.0;
                        }
                        (None, None) => {}
                    }
                }
                Some(acc.into_iter().map(|a| a / n_used).collect())
            })
            .collect();
    }
    // Differences and down: F_l = F_{l-1}(parent) + D_l.
    let mut f: Vec<f64> = g[0][0].clone().unwrap_or_else(|| vec![0.0; ch]);
    for l in 1..levels {
        let side = 1usize << l;
        let mut next = vec![0.0; side * side * ch];
        for node in 0..side * side {
            let (x, y) = (node % side, node / side);
            let parent = (y / 2) * (side / 2) + x / 2;
            for c in 0..ch {
                let d = match (&g[l][node], &g[l - 1][parent]) {
                    (Some(a), Some(b)) => a[c] - b[c],
                    _ => 0.0,
                };
                next[node * ch + c] = f[parent * ch + c] + d;
            }
        }
        f = next;
    }
    let coarse_only =
        counts[levels - 1].iter().filter(|&&k| k == 0).count() as f64 / (n * n) as f64;
    let tex = Texture::new(n, n, ch, f.into_iter().map(|x| x as f32).collect())?;
    Ok((
        tex,
        FusionReport {
            offered,
            rejected,
            coarse_only_fraction: coarse_only,
            seconds: start.elapsed().as_secs_f64(),
        },
    ))
}

/// A disc occluder in texture coordinates.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Occluder {
    /// Centre `(u, v)`.
    pub centre: [f64; 2],
    /// Radius in texture units.
    pub radius: f64,
    /// Value of every channel where it covers a pixel centre.
    pub value: f32,
}

/// Synthetic registered views of `truth` (`n × n`, `n` a power of two): view `k` at scale
/// `scales[k]` (exact box means of the truth over each pixel, plus uniform noise of amplitude
/// `noise`), with the occluder — shifted by `0.02·k` in `u` for parallax — where `occluded[k]`.
pub fn synthetic_views(
    truth: &Texture,
    scales: &[u32],
    occluded: &[bool],
    occluder: Occluder,
    noise: f64,
    seed: u64,
) -> Vec<FusionView> {
    let n = truth.width;
    let ch = truth.channels;
    let data: Vec<f64> = truth.data.iter().map(|&x| f64::from(x)).collect();
    let mut rng = SplitMix64::new(seed);
    scales
        .iter()
        .enumerate()
        .map(|(k, &m)| {
            let s = n >> m;
            let mut img = reduce(&data, n, ch, m);
            let shift = 0.02 * k as f64;
            for y in 0..s {
                for x in 0..s {
                    let (u, v) = ((x as f64 + 0.5) / s as f64, (y as f64 + 0.5) / s as f64);
                    let inside = occluded.get(k).copied().unwrap_or(false)
                        && (u - occluder.centre[0] - shift).hypot(v - occluder.centre[1])
                            < occluder.radius;
                    for c in 0..ch {
                        let px = &mut img[(y * s + x) * ch + c];
                        if inside {
                            *px = f64::from(occluder.value);
                        }
                        *px += noise * (2.0 * rng.next_f64() - 1.0);
                    }
                }
            }
            FusionView {
                image: Texture {
                    width: s,
                    height: s,
                    channels: ch,
                    data: img.into_iter().map(|x| x as f32).collect(),
                },
                scale_log2: m,
            }
        })
        .collect()
}

/// PSNR in dB of `a` against `b` (peak 1); `f64::INFINITY` when equal. Sizes must match.
pub fn psnr(a: &Texture, b: &Texture) -> f64 {
    let mse = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(x, y)| f64::from(x - y).powi(2))
        .sum::<f64>()
        / a.data.len().max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

/// The fusion experiment of the report: a `n × n` smooth 3-channel texture, five views at
/// scales `0, 0, 0, 1, 1`, a dark disc occluder in views 1 and 3 (two of five), noise 0.01;
/// returns the PSNR with and without rejection and the rejecting run's report.
pub fn fusion_experiment(n: usize, seed: u64) -> Result<FusionExperiment, MipError> {
    let truth = super::truth::test_texture(n, seed);
    // Three channels: the test texture and two shifted copies.
    let ch3: Vec<f32> = (0..n * n)
        .flat_map(|k| {
            let (i, j) = (k % n, k / n);
            [
                truth.data[k],
                truth.data[j * n + (i + n / 3) % n],
                truth.data[((j + n / 5) % n) * n + i],
            ]
        })
        .collect();
    let truth = Texture::new(n, n, 3, ch3)?;
    let occluder = Occluder {
        centre: [0.45, 0.5],
        radius: 0.2,
        value: 0.02,
    };
    let views = synthetic_views(
        &truth,
        &[0, 0, 0, 1, 1],
        &[false, true, false, true, false],
        occluder,
        0.01,
        seed,
    );
    let (with, report) = fuse(&views, n, &FusionParams::default())?;
    let (without, _) = fuse(
        &views,
        n,
        &FusionParams {
            reject: false,
            ..Default::default()
        },
    )?;
    Ok(FusionExperiment {
        psnr_with_rejection: psnr(&with, &truth),
        psnr_without_rejection: psnr(&without, &truth),
        report,
    })
}

/// Result of [`fusion_experiment`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FusionExperiment {
    /// PSNR (dB) of the fused texture against the truth, median rejection on.
    pub psnr_with_rejection: f64,
    /// The same without rejection.
    pub psnr_without_rejection: f64,
    /// Report of the run with rejection.
    pub report: FusionReport,
}
