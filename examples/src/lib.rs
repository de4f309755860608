//! Shared parts of the example programs (`src/bin/*`): the `--window` viewer, and the
//! precompute-write-load step every program that precomputes its asset takes.

pub mod window;

use std::path::Path;

use altrep::asset::{AssetWriter, Conventions};
use altrep::representation::{Needs, Representation, Source};
use altrep_display::Gpu;

/// Plans and builds representation `R` of `source` for `needs` with the pipeline's verbs, writes
/// it with the pipeline's writer under `out/asset/<name>/<R::NAME>` and loads it back through
/// the library's loader, so that a program draws from the files as any user would. A plan
/// that refuses the representation is an error naming the reason.
///
/// Errors: as text, from the plan, the build, the writer or the loader.
pub fn precompute<R: Representation>(
    spec: &R::Spec,
    needs: &Needs,
    source: &Source,
    out: &Path,
) -> Result<R::Data, String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let (plan, decisions) = R::plan(spec, needs, source).map_err(|x| e(&x))?;
    if let Some(why) = &plan.refused {
        return Err(format!("{} refused: {why}", R::NAME));
    }
    let (data, _) = R::build(spec, needs, &decisions, source).map_err(|x| e(&x))?;
    let dir = out.join("asset");
    let mut w = AssetWriter::new(&dir, source.name, R::NAME).map_err(|x| e(&x))?;
    let meta = R::write(&data, &mut w).map_err(|x| e(&x))?;
    w.commit(
        R::NAME,
        source.name,
        "example",
        Conventions::new(1.0, 2.0),
        meta,
        serde_json::Value::Null,
    )
    .map_err(|x| e(&x))?;
    altrep_display::load::<R>(&dir.join(source.name).join(R::NAME)).map_err(|x| e(&x))
}

/// Writes a looping GIF of `frames` frames to `path`, 80 ms each: frame `k` is
/// `draw(k as f64 / frames as f64)`, which returns the image (premultiplied linear RGBA, shown
/// over `background`, each pixel `scale × scale`), its time in milliseconds and its PSNR in dB.
/// Returns the times and the worst PSNR. Errors: the file, the encoder or `draw`'s.
pub fn write_turntable(
    path: &Path,
    frames: usize,
    background: [f32; 3],
    scale: u32,
    mut draw: impl FnMut(f64) -> Result<(altrep_display::RgbaImage, f64, f64), String>,
) -> Result<(Vec<f64>, f64), String> {
    use image::codecs::gif::{GifEncoder, Repeat};
    use image::{Delay, Frame};
    let e = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let file = std::fs::File::create(path).map_err(|x| e(&x))?;
    let mut enc = GifEncoder::new_with_speed(std::io::BufWriter::new(file), 10);
    enc.set_repeat(Repeat::Infinite).map_err(|x| e(&x))?;
    let frames = frames.max(1);
    let (mut ms, mut worst) = (Vec::with_capacity(frames), f64::INFINITY);
    for k in 0..frames {
        let (img, t, db) = draw(k as f64 / frames as f64)?;
        ms.push(t);
        worst = worst.min(db);
        let frame = Frame::from_parts(
            altrep_display::to_srgb8(&img, background, scale),
            0,
            0,
            Delay::from_numer_denom_ms(80, 1),
        );
        enc.encode_frame(frame).map_err(|x| e(&x))?;
    }
    Ok((ms, worst))
}

/// The line every program prints after its animation: the median of `ms` (milliseconds per
/// frame, sorted here) and what the time measures on `gpu` (a CPU adapter emulates the GPU).
pub fn median_frame_time(gpu: &Gpu, ms: &mut [f64]) -> String {
    ms.sort_by(f64::total_cmp);
    let median = ms.get(ms.len() / 2).copied().unwrap_or(f64::NAN);
    let what = if gpu.info.device_type == altrep_display::wgpu::DeviceType::Cpu {
        "CPU emulation, not GPU time"
    } else {
        "GPU"
    };
    format!("median {median:.2} ms per frame incl. read-back ({what})")
}
