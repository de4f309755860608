//! The file side of images with parallax: size checks, the bound codes and their images, and the
//! impostor atlas written beside the views and checked against them on reading. The layout of
//! every file is in the parent module's documentation.

use crate::asset::{AssetReader, AssetWriter, Channel, CodeImage, Encoding};
use serde_json::json;

use super::{ParallaxData, ParallaxDecisions};
use crate::parallax::{BoundKind, Bounds, ParallaxImages, PixelBound, ViewStorage};
use crate::representation::PipelineError;

pub(super) fn check_size<T>(
    r: &AssetReader,
    img: &CodeImage<T>,
    w: usize,
    h: usize,
    channels: usize,
    what: &str,
) -> Result<(), PipelineError> {
    if (img.width, img.height, img.channels) != (w, h, channels) {
        return Err(r
            .content(format!(
                "{what} image is {}×{}×{}, expected {w}×{h}×{channels}",
                img.width, img.height, img.channels
            ))
            .into());
    }
    Ok(())
}

/// Code of a `c` value on the view's grid: 1 = −1, 2 = +1, `q + 3` otherwise.
pub(super) fn c_code(c: f64, grid: Option<(f64, f64)>) -> Result<u16, String> {
    if c == -1.0 {
        return Ok(1);
    }
    if c == 1.0 {
        return Ok(2);
    }
    let (c0, step) = grid.ok_or("a c value off ±1 without a grid")?;
    let q = ((c - c0) / step).round();
    if c0 + q * step != c || !(0.0..=65532.0).contains(&q) {
        return Err(format!("c = {c} is not on the storage grid"));
    }
    Ok(q as u16 + 3)
}

pub(super) fn write_bounds(
    w: &mut AssetWriter,
    b: &Bounds,
    k: usize,
    wd: usize,
    ht: usize,
) -> Result<(), PipelineError> {
    let slots_used = if matches!(b.kind, BoundKind::FPair | BoundKind::BestCSplit) {
        2
    } else {
        1
    };
    let store = b.view_storage(k).copied().unwrap_or_default();
    let px = b.view_slots(k);
    let bits = b.params.bits;
    let mut c_img = CodeImage::<u16>::new(wd, ht, slots_used);
    let mut v16 = CodeImage::<u16>::new(wd, ht, 2 * slots_used);
    let bad = |reason: String| PipelineError::Spec(format!("bounds {}: {reason}", b.kind.slug()));
    for (idx, slots) in px.iter().enumerate() {
        for (s, slot) in slots.iter().enumerate().take(slots_used) {
            let Some(pb) = *slot else { continue };
            c_img.pixel_mut(idx)[s] = c_code(pb.c, store.c_grid).map_err(bad)?;
            for (ch, v) in [pb.v_min, pb.v_max].into_iter().enumerate() {
                let (lo, step) = store.v_grid[s][ch].ok_or_else(|| bad("no v grid".into()))?;
                let q = ((v - lo) / step).round();
                if lo + q * step != v || q < 0.0 || q >= (1u64 << bits) as f64 {
                    return Err(bad(format!("v = {v} is not on the storage grid")));
                }
                v16.pixel_mut(idx)[2 * s + ch] = q as u16;
            }
        }
    }
    let mut v_channels = Vec::new();
    for s in 0..slots_used {
        for (ch, name) in ["v_min", "v_max"].iter().enumerate() {
            let (offset, scale) = store.v_grid[s][ch].unwrap_or((0.0, 0.0));
            v_channels.push(Channel {
                name: format!("slot{s}.{name}"),
                encoding: Encoding::Linear { scale, offset },
            });
        }
    }
    let (c0, cstep) = store.c_grid.unwrap_or((0.0, 0.0));
    let c_channels = (0..slots_used)
        .map(|s| Channel {
            name: format!(
                "slot{s}.c (code 0 = empty slot, 1 = -1, 2 = +1, q + 3 = offset + q·scale)"
            ),
            encoding: Encoding::Linear {
                scale: cstep,
                offset: c0,
            },
        })
        .collect();
    let slug = b.kind.slug();
    w.png16(
        &format!("view{k}/bounds/{slug}/c"),
        &format!("view{k}-bounds-{slug}-c.png"),
        &c_img,
        c_channels,
    )?;
    let role = format!("view{k}/bounds/{slug}/v");
    let file = format!("view{k}-bounds-{slug}-v.png");
    if bits == 16 {
        w.png16(&role, &file, &v16, v_channels)?;
    } else {
        let v8 = CodeImage {
            width: wd,
            height: ht,
            channels: v16.channels,
            data: v16.data.iter().map(|&q| q as u8).collect(),
        };
        w.png8(&role, &file, &v8, v_channels)?;
    }
    Ok(())
}

type SlotRow = Vec<[Option<PixelBound>; 2]>;

pub(super) fn read_bounds(
    r: &AssetReader,
    kind: BoundKind,
    bits: u32,
    k: usize,
    wd: usize,
    ht: usize,
) -> Result<(SlotRow, ViewStorage), PipelineError> {
    let slug = kind.slug();
    let slots_used = if matches!(kind, BoundKind::FPair | BoundKind::BestCSplit) {
        2
    } else {
        1
    };
    let c_role = format!("view{k}/bounds/{slug}/c");
    let v_role = format!("view{k}/bounds/{slug}/v");
    let c_img = r.png16(&c_role)?;
    check_size(r, &c_img, wd, ht, slots_used, "bound c")?;
    let v_img: CodeImage<u16> = if bits == 16 {
        r.png16(&v_role)?
    } else {
        let v = r.png8(&v_role)?;
        CodeImage {
            width: v.width,
            height: v.height,
            channels: v.channels,
            data: v.data.into_iter().map(u16::from).collect(),
        }
    };
    check_size(r, &v_img, wd, ht, 2 * slots_used, "bound v")?;
    let linear = |role: &str, i: usize| -> Result<(f64, f64), PipelineError> {
        match r.channels(role)?.get(i).map(|c| &c.encoding) {
            Some(Encoding::Linear { scale, offset }) => Ok((*offset, *scale)),
            _ => Err(r
                .content(format!("{role}: channel {i} is not linear"))
                .into()),
        }
    };
    let mut store = ViewStorage::default();
    for s in 0..slots_used {
        for ch in 0..2 {
            store.v_grid[s][ch] = Some(linear(&v_role, 2 * s + ch)?);
        }
    }
    let (c0, c_step) = linear(&c_role, 0)?;
    store.c_grid = Some((c0, c_step));
    let mut px = vec![[None, None]; wd * ht];
    for (idx, out) in px.iter_mut().enumerate() {
        for (s, slot) in out.iter_mut().enumerate().take(slots_used) {
            let code = c_img.pixel(idx)[s];
            if code == 0 {
                continue;
            }
            let c = match code {
                1 => -1.0,
                2 => 1.0,
                q => c0 + f64::from(q - 3) * c_step,
            };
            let v = |ch: usize| {
                let (lo, step) = store.v_grid[s][ch].unwrap_or_default();
                lo + f64::from(v_img.pixel(idx)[2 * s + ch]) * step
            };
            *slot = Some(PixelBound {
                c,
                v_min: v(0),
                v_max: v(1),
            });
        }
    }
    Ok((px, store))
}

/// Colour of an 8-channel view level (premultiplied linear albedo and coverage, channels 0–3)
/// as a 4-channel texture.
pub(super) fn colour_of(t: &crate::pyramid::Texture) -> crate::pyramid::Texture {
    crate::pyramid::Texture {
        width: t.width,
        height: t.height,
        channels: 4,
        data: t
            .data
            .chunks_exact(t.channels)
            .flat_map(|c| [c[0], c[1], c[2], c[3]])
            .collect(),
    }
}

/// A premultiplied linear RGBA level as RGBA8: straight sRGB colour, coverage in alpha
/// ([`CodeImage::from_premultiplied`]).
pub(super) fn rgba8_of(t: &crate::pyramid::Texture) -> CodeImage<u8> {
    CodeImage::from_premultiplied(t.width, t.height, t.channels, &t.data)
}

/// The impostor atlas of the present views of `images` and its pyramid: transparent gutters
/// wide enough that no level up to the coarsest kept mip level bleeds between frames
/// ([`crate::pyramid::atlas`], box filter, premultiplied linear colour and coverage).
pub(super) fn atlas_pyramid(
    images: &ParallaxImages,
    d: &ParallaxDecisions,
) -> Result<(crate::pyramid::atlas::AtlasLayout, crate::pyramid::Pyramid), PipelineError> {
    use crate::pyramid::atlas::{AtlasLayout, GutterFill};
    use crate::pyramid::{Filter, Pyramid, PyramidParams};
    let p = &images.params;
    let clean = d.mip_levels.iter().copied().max().unwrap_or(0);
    let layout = AtlasLayout::new(d.views.len(), p.width, p.height, clean, Filter::Box)?;
    let frames: Vec<_> = d
        .views
        .iter()
        .map(|&k| colour_of(&images.pyramids()[k].levels()[0]))
        .collect();
    let atlas = Pyramid::build(
        layout.pack(&frames, GutterFill::Transparent)?,
        PyramidParams::default(),
    )?;
    Ok((layout, atlas))
}

/// Writes the impostor atlas ([`atlas_pyramid`]) at level 0 and at the mip levels the planner
/// kept: `atlas-mip{l}.png` (RGBA8, straight sRGB colour, coverage). Returns the metadata
/// (layout and levels), `null` without views.
pub(super) fn write_atlas(
    data: &ParallaxData,
    w: &mut AssetWriter,
) -> Result<serde_json::Value, PipelineError> {
    use crate::pyramid::Filter;
    use crate::pyramid::atlas::GutterFill;
    let d = &data.decisions;
    if d.views.is_empty() {
        return Ok(serde_json::Value::Null);
    }
    let (layout, atlas) = atlas_pyramid(&data.images, d)?;
    let levels: Vec<usize> = std::iter::once(0)
        .chain(d.mip_levels.iter().copied())
        .collect();
    let ch = |name: &str, encoding: Encoding| Channel {
        name: name.into(),
        encoding,
    };
    for &l in &levels {
        w.png8(
            &format!("atlas/mip{l}"),
            &format!("atlas-mip{l}.png"),
            &rgba8_of(&atlas.levels()[l]),
            vec![
                ch("colour.r", Encoding::Srgb),
                ch("colour.g", Encoding::Srgb),
                ch("colour.b", Encoding::Srgb),
                ch(
                    "coverage",
                    Encoding::Linear {
                        scale: 1.0 / 255.0,
                        offset: 0.0,
                    },
                ),
            ],
        )?;
    }
    Ok(json!({
        "layout": layout,
        "levels": levels,
        "frames": d.views,
        "gutter_fill": GutterFill::Transparent,
        "filter": Filter::Box,
    }))
}

/// Loads the atlas levels written by [`write_atlas`] (if any) and checks them: the layout is
/// the one the loaded views call for, the levels are level 0 and the kept mip levels, and every
/// texel of every level is within 2 steps of the atlas rebuilt from the loaded views (colour
/// where covered, coverage everywhere; the views were quantised to 8 bits in between).
pub(super) fn verify_atlas(
    r: &AssetReader,
    images: &ParallaxImages,
    decisions: &ParallaxDecisions,
) -> Result<(), PipelineError> {
    use crate::pyramid::atlas::AtlasLayout;
    let m = &r.description().metadata["atlas"];
    if m.is_null() || decisions.views.is_empty() {
        return Ok(());
    }
    let layout: AtlasLayout = serde_json::from_value(m["layout"].clone())
        .map_err(|e| r.content(format!("metadata.atlas.layout: {e}")))?;
    let levels: Vec<usize> = serde_json::from_value(m["levels"].clone())
        .map_err(|e| r.content(format!("metadata.atlas.levels: {e}")))?;
    let (want_layout, atlas) = atlas_pyramid(images, decisions)?;
    let want_levels: Vec<usize> = std::iter::once(0)
        .chain(decisions.mip_levels.iter().copied())
        .collect();
    if layout != want_layout || levels != want_levels {
        return Err(r
            .content("metadata.atlas: the layout or levels do not fit the views".into())
            .into());
    }
    for &l in &levels {
        let img = r.png8(&format!("atlas/mip{l}"))?;
        let want = rgba8_of(&atlas.levels()[l]);
        check_size(r, &img, want.width, want.height, 4, "atlas level")?;
        for idx in 0..want.width * want.height {
            let (got, exp) = (img.pixel(idx), want.pixel(idx));
            let colour_ok = exp[3] == 0
                || got
                    .iter()
                    .zip(exp)
                    .take(3)
                    .all(|(a, b)| a.abs_diff(*b) <= 2);
            if !colour_ok || got[3].abs_diff(exp[3]) > 2 {
                return Err(r
                    .content(format!(
                        "atlas level {l}, texel {idx}: {got:?}, the views give {exp:?}"
                    ))
                    .into());
            }
        }
    }
    Ok(())
}
