//! Image comparison helpers for tests and examples: differences, percentiles, failure
//! artefacts. Images are premultiplied linear RGBA (`RgbaImage`).

use std::path::{Path, PathBuf};

use altrep_data_gen::RgbaImage;

use crate::DisplayError;

/// Per pixel, the largest absolute channel difference (RGBA), row-major. Errors: sizes differ.
pub fn pixel_errors(a: &RgbaImage, b: &RgbaImage) -> Result<Vec<f32>, DisplayError> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(DisplayError::InvalidParameter {
            name: "image sizes",
            value: format!("{}×{} vs {}×{}", a.width, a.height, b.width, b.height),
            reason: "must be equal",
        });
    }
    Ok(a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (0..4).map(|c| (p[c] - q[c]).abs()).fold(0.0, f32::max))
        .collect())
}

/// The `q`-quantile (`0 ≤ q ≤ 1`, nearest rank) of `values`; 0 for an empty slice.
pub fn quantile(values: &[f32], q: f64) -> f32 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(f32::total_cmp);
    let rank = (q.clamp(0.0, 1.0) * (v.len() - 1) as f64).round() as usize;
    v[rank]
}

/// An opaque grey image of the per-pixel error, amplified `gain` times (white = `1/gain`).
pub fn difference_image(
    a: &RgbaImage,
    b: &RgbaImage,
    gain: f32,
) -> Result<RgbaImage, DisplayError> {
    let e = pixel_errors(a, b)?;
    Ok(RgbaImage {
        width: a.width,
        height: a.height,
        pixels: e
            .iter()
            .map(|&x| {
                let g = (x * gain).min(1.0);
                [g, g, g, 1.0]
            })
            .collect(),
    })
}

/// Writes `<dir>/<name>-actual.png`, `-expected.png` and `-difference.png` (error ×10) and
/// returns the folder. Errors: the folder or a file cannot be written, sizes differ.
pub fn write_artefacts(
    dir: &Path,
    name: &str,
    actual: &RgbaImage,
    expected: &RgbaImage,
) -> Result<PathBuf, DisplayError> {
    let io = |p: &Path, e: &dyn std::fmt::Display| DisplayError::File {
        path: p.display().to_string(),
        reason: e.to_string(),
    };
    std::fs::create_dir_all(dir).map_err(|e| io(dir, &e))?;
    let diff = difference_image(actual, expected, 10.0)?;
    for (suffix, img) in [
        ("actual", actual),
        ("expected", expected),
        ("difference", &diff),
    ] {
        let path = dir.join(format!("{name}-{suffix}.png"));
        img.write_png(&path).map_err(|e| io(&path, &e))?;
    }
    Ok(dir.to_path_buf())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    fn img(values: &[f32]) -> RgbaImage {
        RgbaImage {
            width: values.len(),
            height: 1,
            pixels: values.iter().map(|&v| [v, 0.0, 0.0, 1.0]).collect(),
        }
    }

    #[test]
    fn errors_and_quantiles() {
        let a = img(&[0.0, 0.5, 1.0, 0.25]);
        let b = img(&[0.0, 0.25, 0.0, 0.25]);
        let e = pixel_errors(&a, &b).unwrap();
        assert_eq!(e, vec![0.0, 0.25, 1.0, 0.0]);
        assert_abs_diff_eq!(quantile(&e, 1.0), 1.0);
        assert_abs_diff_eq!(quantile(&e, 0.0), 0.0);
        assert_abs_diff_eq!(quantile(&e, 0.67), 0.25);
        assert_abs_diff_eq!(quantile(&[], 0.5), 0.0);
        let d = difference_image(&a, &b, 10.0).unwrap();
        assert_eq!(d.pixels[1], [1.0, 1.0, 1.0, 1.0]);
        assert!(matches!(
            pixel_errors(&a, &img(&[0.0])),
            Err(DisplayError::InvalidParameter { .. })
        ));
    }

    #[test]
    fn artefacts_are_three_pngs() {
        let dir = tempfile::tempdir().unwrap();
        let a = img(&[0.0, 0.5]);
        write_artefacts(dir.path(), "x", &a, &a).unwrap();
        for s in ["actual", "expected", "difference"] {
            assert!(dir.path().join(format!("x-{s}.png")).is_file());
        }
    }
}
