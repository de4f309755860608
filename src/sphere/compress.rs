//! Block-compressed frames (docs/design.md §7b, "Compressed memory"): what the frames cost and
//! lose once stored as a GPU samples them.
//!
//! GPUs sample block-compressed textures directly: 4 × 4 texels in 16 bytes (BC7 for colour with
//! alpha, BC5 for two channels), one byte per texel. Both methods are counted and drawn from the
//! decoded blocks, each in the layout it would ship with:
//!
//! * **Engine baseline**, as engine bakers ship their impostor atlases: two BC7 atlases, the sRGB
//!   albedo with coverage in alpha, and the normal (the stored 8-bit codes) with the depth in
//!   alpha (8 bits over the bounding sphere's `[−1, 1]`). **2 bytes per texel.** A texel is
//!   defined where the decoded coverage is at least ½.
//! * **Exact warp**: the sRGB albedo in BC7 (coverage lives in the depth); the normal as
//!   octahedral coordinates (the whole-sphere map of [`ViewSet::encode`]) in BC5; the depth
//!   uncompressed (16 bits: the march meets the surface at its depth, and a block's endpoints
//!   would move outlines and steps); the cone bounds uncompressed (8 + 8 bits), **built again
//!   from the decoded frames**, so they stay conservative for what is drawn. **6 bytes per
//!   texel**, or 4.5 with bounds over 2 × 2 texels ([`SphereParams::bounds_block`]). With
//!   [`Storage::CompressedDepth8`] the depth takes 8 bits, as the baseline's: 5 bytes per
//!   texel, 3.5 with 2 × 2 bounds.
//!
//! Before encoding, every undefined texel takes its nearest defined texel's values (bakers
//! dilate their atlases the same way), so a block on an outline does not mix the object with the
//! empty background. Frame sides are padded up to a multiple of 4 (the padding repeats the last
//! row and column) and the padding is counted in the bytes.
//!
//! The encoder is Intel's ISPC texture compressor (`intel_tex_2`, "basic" quality, the level
//! offline bakers use); the decoder `bcdec_rs` decodes as the GPU's fixed-function units do.
//! Both start from the raw frames' codes, so the compressed error adds to the raw quantisation's.
//! Cost: four atlases of `G²·F²` texels encoded (BC7 the slow part; measured about 6 s per
//! million texels for the four on one core: 16 × 16 frames of 256² took 49 s on two), then the
//! bounds again (as [`SphereImages::capture`]).

use std::time::Instant;

use glam::{DVec2, Vec3};
use intel_tex_2::{RgSurface, RgbaSurface, bc5, bc7};
use rayon::prelude::*;

use super::bounds::ConeBounds;
use super::frames::{depth_code, depth_value, nearest_defined};
use super::{Coverage, Frame, FrameCodes, SphereError, SphereImages, SphereParams, ViewSet};
use crate::parallax::normal_code;

/// How the frames are held in memory when they are counted and drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Storage {
    /// The stored codes as they are: 8 bytes per texel of frame, 2 of bounds.
    #[default]
    Raw,
    /// Block-compressed as a GPU samples them (module docs): 2 bytes per texel for the engine
    /// baseline, 6 for the exact warp (4.5 with bounds over 2 × 2 texels).
    Compressed,
    /// As [`Storage::Compressed`], with the exact warp's depth in 8 bits instead of 16 (an R8
    /// texture: 0 undefined, 255 levels over the bounding sphere's `[−1, 1]`, the baseline's
    /// depth precision): 5 bytes per texel, 3.5 with bounds over 2 × 2 texels. The bounds are
    /// built from the 8-bit depth, so they hold for what is drawn.
    CompressedDepth8,
}

impl Storage {
    /// Whether the frames are block-compressed.
    pub fn is_compressed(self) -> bool {
        self != Self::Raw
    }

    /// Bits of the exact warp's stored depth: 8 for [`Storage::CompressedDepth8`], else 16.
    pub fn warp_depth_bits(self) -> u32 {
        match self {
            Self::CompressedDepth8 => 8,
            Self::Raw | Self::Compressed => 16,
        }
    }
}

impl SphereParams {
    /// Texels of one frame once its sides are padded up to whole 4 × 4 blocks.
    pub fn block_texels(&self) -> usize {
        let p = self.size.div_ceil(4) * 4;
        p * p
    }

    /// Bytes of the engine baseline's frames in `storage`: raw, [`Self::frame_bytes`];
    /// compressed, two BC7 atlases of one byte per padded texel.
    pub fn baseline_bytes(&self, storage: Storage) -> usize {
        match storage {
            Storage::Raw => self.frame_bytes(),
            Storage::Compressed | Storage::CompressedDepth8 => {
                self.set.len() * self.block_texels() * 2
            }
        }
    }

    /// Bytes of the exact warp's frames and bounds in `storage`: raw, [`Self::total_bytes`];
    /// compressed, BC7 albedo and BC5 normal (one byte per padded texel each), then 16-bit
    /// (8-bit for [`Storage::CompressedDepth8`]) depth per texel and 8 + 8-bit bounds per
    /// bounds texel ([`Self::bounds_block`]).
    pub fn warp_bytes(&self, storage: Storage) -> usize {
        match storage {
            Storage::Raw => self.total_bytes(),
            Storage::Compressed | Storage::CompressedDepth8 => {
                let depth = storage.warp_depth_bits() as usize / 8;
                self.set.len() * (self.block_texels() * 2 + self.size * self.size * depth)
                    + self.bounds_bytes()
            }
        }
    }
}

/// The frames of one [`SphereImages`] after block compression, each method in its own layout
/// (module docs).
#[derive(Clone, Debug)]
pub struct CompressedFrames {
    /// What the exact warp draws: BC7 albedo, BC5 octahedral normals, raw depth, bounds rebuilt
    /// from the decoded frames. Its `codes` hold the decoded albedo and the decoded normals
    /// quantised back to 8-bit codes (the frames themselves keep the decoded normals unquantised).
    pub warp: SphereImages,
    /// What the engine baseline draws: every channel decoded from its two BC7 atlases.
    pub baseline: SphereImages,
    /// Wall time of the encoding and decoding, both layouts (s).
    pub encode_s: f64,
}

/// The padded `p × p` image (`p` the side rounded up to 4) of `f × f` per-texel values, the
/// padding repeating the last row and column. `value(k, n)` gives the channels of texel `k`,
/// whose nearest defined texel is `n` (itself where defined): what an undefined texel is
/// dilated with.
fn padded<const C: usize>(
    f: usize,
    nearest: Option<&[usize]>,
    value: impl Fn(usize, usize) -> [u8; C],
) -> (usize, Vec<u8>) {
    let p = f.div_ceil(4) * 4;
    let mut out = vec![0u8; p * p * C];
    let Some(nearest) = nearest else {
        return (p, out);
    };
    for y in 0..p {
        for x in 0..p {
            let k = y.min(f - 1) * f + x.min(f - 1);
            let o = (y * p + x) * C;
            out[o..o + C].copy_from_slice(&value(k, nearest[k]));
        }
    }
    (p, out)
}

/// Decodes `p × p` texels of `C` bytes from row-major 16-byte blocks with `decode(block, out,
/// pitch)`.
fn decode_blocks<const C: usize>(
    p: usize,
    blocks: &[u8],
    decode: impl Fn(&[u8], &mut [u8], usize),
) -> Vec<u8> {
    let mut out = vec![0u8; p * p * C];
    let per_row = p / 4;
    for (b, block) in blocks.chunks_exact(16).enumerate() {
        let (bx, by) = (b % per_row, b / per_row);
        let start = (by * 4 * p + bx * 4) * C;
        decode(block, &mut out[start..], p * C);
    }
    out
}

/// BC7 round trip of a padded RGBA8 image.
fn bc7_round_trip(p: usize, rgba: &[u8], settings: &bc7::EncodeSettings) -> Vec<u8> {
    let surface = RgbaSurface {
        data: rgba,
        width: p as u32,
        height: p as u32,
        stride: (p * 4) as u32,
    };
    let blocks = bc7::compress_blocks(settings, &surface);
    decode_blocks::<4>(p, &blocks, bcdec_rs::bc7)
}

/// BC5 round trip of a padded two-channel image.
fn bc5_round_trip(p: usize, rg: &[u8]) -> Vec<u8> {
    let surface = RgSurface {
        data: rg,
        width: p as u32,
        height: p as u32,
        stride: (p * 2) as u32,
    };
    let blocks = bc5::compress_blocks(&surface);
    decode_blocks::<2>(p, &blocks, |b, out, pitch| {
        bcdec_rs::bc5(b, out, pitch, false);
    })
}

/// The whole-sphere octahedral map the normals are stored on.
const NORMAL_MAP: ViewSet = ViewSet {
    coverage: Coverage::Sphere,
    grid: 2,
};

/// Unorm8 code of an octahedral coordinate in `[−1, 1]`.
fn unorm8(e: f64) -> u8 {
    ((e.clamp(-1.0, 1.0) + 1.0) * 0.5 * 255.0).round() as u8
}

/// The engine layout's round trip of one frame's codes: two BC7 atlases decoded back to codes.
fn baseline_codes(codes: &FrameCodes) -> FrameCodes {
    let f = codes.size;
    let defined: Vec<bool> = codes.depth.iter().map(|&d| d != 0).collect();
    let nearest = nearest_defined(&defined, f);
    let near = nearest.as_deref();
    // The coverage is the defined mask itself, not its dilation.
    let (p, colour) = padded::<4>(f, near, |k, n| {
        let a = codes.albedo[n];
        [a[0], a[1], a[2], if defined[k] { 255 } else { 0 }]
    });
    let (_, geometry) = padded::<4>(f, near, |_, n| {
        let c = codes.normal[n];
        [c[0], c[1], c[2], unorm8(depth_value(codes.depth[n]))]
    });
    let settings = bc7::alpha_basic_settings();
    let colour = bc7_round_trip(p, &colour, &settings);
    let geometry = bc7_round_trip(p, &geometry, &settings);
    let mut out = FrameCodes {
        size: f,
        albedo: vec![[0; 3]; f * f],
        normal: vec![[0; 3]; f * f],
        depth: vec![0; f * f],
    };
    for y in 0..f {
        for x in 0..f {
            let (k, o) = (y * f + x, (y * p + x) * 4);
            if colour[o + 3] < 128 {
                continue;
            }
            out.albedo[k] = [colour[o], colour[o + 1], colour[o + 2]];
            out.normal[k] = [geometry[o], geometry[o + 1], geometry[o + 2]];
            out.depth[k] = depth_code(f64::from(geometry[o + 3]) / 255.0 * 2.0 - 1.0);
        }
    }
    out
}

/// A 16-bit depth code through an 8-bit store: 0 stays undefined, a defined depth takes the
/// nearest of 255 levels over `[−1, 1]` (as the baseline's [`unorm8`]).
fn depth8(code: u16) -> u16 {
    if code == 0 {
        return 0;
    }
    depth_code(f64::from(unorm8(depth_value(code))) / 255.0 * 2.0 - 1.0)
}

/// The exact warp's round trip of one frame: BC7 albedo and BC5 octahedral normals, the depth
/// kept at 16 bits or stored in `depth_bits = 8`. Returns the codes (normals re-quantised to
/// 8-bit codes) and the decoded unit normals.
fn warp_codes(frame: &Frame, codes: &FrameCodes, depth_bits: u32) -> (FrameCodes, Vec<Vec3>) {
    let f = codes.size;
    let nearest = nearest_defined(&frame.defined, f);
    let near = nearest.as_deref();
    let (p, colour) = padded::<4>(f, near, |_, n| {
        let a = codes.albedo[n];
        [a[0], a[1], a[2], 255]
    });
    let (_, oct) = padded::<2>(f, near, |_, n| {
        let e = NORMAL_MAP.encode(frame.normal[n].as_dvec3());
        [unorm8(e.x), unorm8(e.y)]
    });
    let colour = bc7_round_trip(p, &colour, &bc7::opaque_basic_settings());
    let oct = bc5_round_trip(p, &oct);
    let mut out = FrameCodes {
        size: f,
        albedo: vec![[0; 3]; f * f],
        normal: vec![[0; 3]; f * f],
        depth: if depth_bits == 8 {
            codes.depth.iter().map(|&c| depth8(c)).collect()
        } else {
            codes.depth.clone()
        },
    };
    let mut normals = vec![Vec3::Z; f * f];
    let dec = |c: u8| f64::from(c) / 255.0 * 2.0 - 1.0;
    for y in 0..f {
        for x in 0..f {
            let (k, o) = (y * f + x, y * p + x);
            if !frame.defined[k] {
                continue;
            }
            out.albedo[k] = [colour[o * 4], colour[o * 4 + 1], colour[o * 4 + 2]];
            let n = NORMAL_MAP
                .decode(DVec2::new(dec(oct[o * 2]), dec(oct[o * 2 + 1])))
                .as_vec3();
            normals[k] = n;
            out.normal[k] = [normal_code(n.x), normal_code(n.y), normal_code(n.z)];
        }
    }
    (out, normals)
}

/// Rebuilds a set from decoded frames: their bounds built again (timed).
fn rebuilt(images: &SphereImages, frames: Vec<Frame>, codes: Vec<FrameCodes>) -> SphereImages {
    let t = Instant::now();
    let bounds = ConeBounds::build_all(&frames, &images.cones, images.params.bounds_block);
    SphereImages {
        params: images.params,
        frames,
        codes,
        cones: images.cones.clone(),
        bounds,
        capture_time: images.capture_time,
        bounds_time: t.elapsed(),
    }
}

/// Block-compresses `images` in both layouts of `storage` (module docs) and decodes them back:
/// what each method draws from a GPU's compressed textures. Frames in parallel. Errors:
/// [`Storage::Raw`] (nothing to compress), a frame that cannot be decoded (codes of the wrong
/// size).
pub fn compress(images: &SphereImages, storage: Storage) -> Result<CompressedFrames, SphereError> {
    super::check(
        storage.is_compressed(),
        "storage",
        format!("{storage:?}"),
        "must be a compressed layout",
    )?;
    let depth_bits = storage.warp_depth_bits();
    let t = Instant::now();
    let model = images.params.model;
    let decoded = images
        .frames
        .par_iter()
        .zip(&images.codes)
        .map(|(fr, codes)| -> Result<_, SphereError> {
            let (wc, normals) = warp_codes(fr, codes, depth_bits);
            let warp = Frame::decode(&fr.frame, &wc, model)?.with_normals(&normals, model)?;
            let bc = baseline_codes(codes);
            let base = Frame::decode(&fr.frame, &bc, model)?;
            Ok(((warp, wc), (base, bc)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let encode_s = t.elapsed().as_secs_f64();
    let (warp, base): (Vec<_>, Vec<_>) = decoded.into_iter().unzip();
    let (wf, wc): (Vec<_>, Vec<_>) = warp.into_iter().unzip();
    let (bf, bc): (Vec<_>, Vec<_>) = base.into_iter().unzip();
    Ok(CompressedFrames {
        warp: rebuilt(images, wf, wc),
        baseline: rebuilt(images, bf, bc),
        encode_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use altrep_data_gen::scene_shape;

    fn truck(grid: usize, size: usize) -> SphereImages {
        let shape = scene_shape("truck").unwrap();
        let p = SphereParams::hemisphere(grid, size).unwrap();
        SphereImages::capture(&shape, &p).unwrap()
    }

    #[test]
    fn compressed_bytes_count_the_padded_blocks() {
        let p = SphereParams::hemisphere(4, 57).unwrap();
        // 57 → 60: 3600 texels per frame in blocks, 3249 raw.
        assert_eq!(p.block_texels(), 3600);
        assert_eq!(p.baseline_bytes(Storage::Compressed), 16 * 3600 * 2);
        assert_eq!(
            p.warp_bytes(Storage::Compressed),
            16 * (3600 * 2 + 3249 * 4)
        );
        assert_eq!(p.baseline_bytes(Storage::Raw), p.frame_bytes());
        assert_eq!(p.warp_bytes(Storage::Raw), p.total_bytes());
        // Bounds of 2 × 2 texels: ⌈57/2⌉² = 841 bounds texels of 2 bytes per frame.
        let p = SphereParams {
            bounds_block: 2,
            ..p
        };
        assert_eq!(
            p.warp_bytes(Storage::Compressed),
            16 * (3600 * 2 + 3249 * 2 + 841 * 2)
        );
        assert_eq!(p.warp_bytes(Storage::Raw), 16 * (3249 * 8 + 841 * 2));
        // The warp's depth in 8 bits: one byte per texel less.
        assert_eq!(
            p.warp_bytes(Storage::CompressedDepth8),
            16 * (3600 * 2 + 3249 + 841 * 2)
        );
        assert_eq!(
            p.baseline_bytes(Storage::CompressedDepth8),
            p.baseline_bytes(Storage::Compressed)
        );
    }

    #[test]
    fn raw_storage_is_not_a_compressed_layout() {
        let e = compress(&truck(2, 8), Storage::Raw).unwrap_err();
        assert!(e.to_string().contains("compressed layout"), "{e}");
    }

    #[test]
    fn compression_keeps_the_outline_and_stays_near_the_codes() {
        let images = truck(3, 30);
        let c = compress(&images, Storage::Compressed).unwrap();
        // Means over the defined texels of every frame: normal angle (degrees), largest albedo
        // channel error (linear), depth error (frame units).
        let (mut n, mut angle, mut albedo_w, mut albedo_b, mut depth_b) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut worst_angle = 0.0f64;
        for (k, raw) in images.frames.iter().enumerate() {
            let (w, b) = (&c.warp.frames[k], &c.baseline.frames[k]);
            // The warp keeps the depth, hence the outline, exactly; the baseline's coverage
            // survives its BC7 alpha (a 0/255 mask).
            assert_eq!(w.defined, raw.defined, "frame {k}");
            assert_eq!(b.defined, raw.defined, "frame {k}");
            assert_eq!(c.warp.codes[k].depth, images.codes[k].depth);
            for t in (0..raw.defined.len()).filter(|&t| raw.defined[t]) {
                let a = f64::from(w.normal[t].dot(raw.normal[t]).clamp(-1.0, 1.0))
                    .acos()
                    .to_degrees();
                worst_angle = worst_angle.max(a);
                angle += a;
                albedo_w += f64::from((w.albedo[t] - raw.albedo[t]).abs().max_element());
                albedo_b += f64::from((b.albedo[t] - raw.albedo[t]).abs().max_element());
                depth_b += (b.depth[t] - raw.depth[t]).abs();
                n += 1.0;
            }
        }
        // Measured: 0.127°, worst 7.3°; albedo 0.0005 (opaque BC7) and 0.0155 (BC7 with the
        // coverage in alpha); the baseline's 8-bit depth 0.0073, about one step of 2/255.
        assert!(
            angle / n < 0.25 && worst_angle < 10.0,
            "{} {worst_angle}",
            angle / n
        );
        assert!(albedo_w / n < 0.002, "{}", albedo_w / n);
        assert!(albedo_b / n < 0.03, "{}", albedo_b / n);
        assert!(depth_b / n < 1.5 * 2.0 / 255.0, "{}", depth_b / n);
    }

    #[test]
    fn bounds_rebuilt_from_the_decoded_frames_hold() {
        let images = truck(3, 32);
        for storage in [Storage::Compressed, Storage::CompressedDepth8] {
            let c = compress(&images, storage).unwrap();
            let dirs = crate::sphere::fibonacci_directions(40, Coverage::Hemisphere);
            let check = crate::sphere::check_bounds(&c.warp, &dirs, 24).unwrap();
            assert!(check.marches > 0);
            assert_eq!(
                check.violations, 0,
                "{storage:?}: worst excess {:e}",
                check.worst_excess
            );
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 200, rng_seed: proptest::test_runner::RngSeed::Fixed(20261207), ..proptest::prelude::ProptestConfig::default() })]
        /// Random frames of any size (padded to whole blocks or not), empty, full or holed,
        /// with random codes: the warp's round trip keeps every texel's coverage and depth code
        /// and decodes finite unit normals; the baseline's decodes a valid frame. Its coverage,
        /// in BC7 alpha beside random colours, can flip: BC7 modes that share one index per
        /// texel between colour and alpha spend it on the colour noise (this test found such a
        /// texel). On captured frames it is kept (the test above).
        #[test]
        fn round_trips_keep_coverage_on_random_frames(
            f in 1usize..14,
            hole_share in proptest::prop_oneof![proptest::strategy::Just(0.0f64), proptest::strategy::Just(1.0), 0.0f64..1.0],
            texels in proptest::collection::vec((0.0f64..1.0, 1u16..=u16::MAX, proptest::array::uniform3(0u8..=255), proptest::array::uniform3(0u8..=255)), 13 * 13),
        ) {
            let mut codes = FrameCodes {
                size: f,
                albedo: vec![[0; 3]; f * f],
                normal: vec![[0; 3]; f * f],
                depth: vec![0; f * f],
            };
            for (k, &(u, d, a, n)) in texels.iter().enumerate().take(f * f) {
                if u >= hole_share {
                    codes.depth[k] = d;
                    codes.albedo[k] = a;
                    codes.normal[k] = n;
                }
            }
            let of = altrep_data_gen::OrthoFrame::new(glam::DVec3::ZERO, 1.0, glam::DVec3::Y).unwrap();
            let model = super::super::SurfaceModel::DEFAULT;
            let frame = Frame::decode(&of, &codes, model).unwrap();
            let (wc, normals) = warp_codes(&frame, &codes, 16);
            proptest::prop_assert_eq!(&wc.depth, &codes.depth);
            // In 8 bits: the same coverage, each depth within half an 8-bit step (plus half a
            // 16-bit code).
            let (w8, _) = warp_codes(&frame, &codes, 8);
            for (&a, &b) in w8.depth.iter().zip(&codes.depth) {
                proptest::prop_assert_eq!(a == 0, b == 0);
                if b != 0 {
                    proptest::prop_assert!((depth_value(a) - depth_value(b)).abs() <= 1.0 / 255.0 + 1.0 / 65534.0);
                }
            }
            let warp = Frame::decode(&of, &wc, model).unwrap().with_normals(&normals, model).unwrap();
            proptest::prop_assert_eq!(&warp.defined, &frame.defined);
            for (k, n) in warp.normal.iter().enumerate() {
                if warp.defined[k] {
                    proptest::prop_assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-5, "{n}");
                }
            }
            let bc = baseline_codes(&codes);
            let base = Frame::decode(&of, &bc, model).unwrap();
            for k in (0..f * f).filter(|&k| base.defined[k]) {
                proptest::prop_assert!(base.depth[k].abs() <= 1.0 && base.normal[k].is_finite());
                proptest::prop_assert!(base.albedo[k].is_finite() && base.slope[k].is_finite());
            }
        }
    }
}
