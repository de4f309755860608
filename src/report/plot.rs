//! Plots of a [`RepresentationReport`]: one panel per cost axis (cost across, error up), one
//! colour per series, the source documents' operating points circled and named, their other
//! claims as dashed vertical lines. Each series' points on its cost–error front (no cheaper or
//! equally cheap point of the series has an error as good) are filled and joined by a line in
//! order of cost; the points it dominates are drawn hollow, unjoined, so a sweep over two
//! parameters reads as one curve of the settings worth their cost.
//!
//! Drawn with `plotters`, as SVG (text as `<text>` elements) and PNG (text rasterised with
//! DejaVu Sans, embedded in the binary by the `dejavu` crate and registered with plotters'
//! `ab_glyph` backend: no system font is read, so PNGs come out the same on a bare machine).
//!
//! A cost axis whose values are all positive and span more than a factor 20 is drawn on a log
//! scale (ticks labelled with the values, the axis name says "log").

use std::sync::Once;

use plotters::chart::MeshStyle;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use super::{Cost, ReportError, RepresentationReport};

/// Width of one panel, pixels.
pub const PANEL_WIDTH: u32 = 520;
/// Height of a plot, pixels.
pub const PLOT_HEIGHT: u32 = 440;
/// The font family every text uses (registered once from the embedded DejaVu Sans).
const FONT: &str = "sans-serif";

fn register_font() -> Result<(), String> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
            .map_err(|_| "the embedded DejaVu Sans font is not a valid font".to_string());
    });
    result
}

fn plot_err(name: &str) -> impl Fn(String) -> ReportError + '_ {
    move |message| ReportError::Plot {
        name: name.to_string(),
        message,
    }
}

/// The plot's size in pixels.
pub fn size(r: &RepresentationReport) -> (u32, u32) {
    (PANEL_WIDTH * r.panels.len().max(1) as u32, PLOT_HEIGHT)
}

/// The plot as an SVG document.
pub fn svg(r: &RepresentationReport) -> Result<String, ReportError> {
    register_font().map_err(plot_err(r.name))?;
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, size(r)).into_drawing_area();
        draw(&root, r).map_err(plot_err(r.name))?;
        root.present()
            .map_err(|e| plot_err(r.name)(e.to_string()))?;
    }
    Ok(s)
}

/// The plot as PNG bytes.
pub fn png(r: &RepresentationReport) -> Result<Vec<u8>, ReportError> {
    register_font().map_err(plot_err(r.name))?;
    let (w, h) = size(r);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw(&root, r).map_err(plot_err(r.name))?;
        root.present()
            .map_err(|e| plot_err(r.name)(e.to_string()))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf)
        .ok_or_else(|| plot_err(r.name)("pixel buffer of the wrong size".into()))?;
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| plot_err(r.name)(e.to_string()))?;
    Ok(out.into_inner())
}

/// One line of [`error_against_size`]: a chain's name and its `(screen size in pixels, PSNR in
/// dB)` points.
#[derive(Clone, Debug, PartialEq)]
pub struct SizeLine {
    /// Name in the legend.
    pub name: String,
    /// `(screen size, PSNR)` points; non-finite ones are left out.
    pub points: Vec<(f64, f64)>,
}

/// Width and height of [`error_against_size`]'s picture, pixels: the plot, and the legend on
/// its right.
pub const SIZE_PLOT: (u32, u32) = (760, 400);

/// Width of the legend of [`error_against_size`], pixels.
const SIZE_LEGEND: u32 = 230;

/// A plot of error against screen size: screen size across (pixels, log₂ scale, ticks at the
/// powers of two), PSNR up (dB), one colour per line (points joined in order of size, drawn
/// filled), the first line drawn first and wide, so that it shows around any line drawn over it
/// with the same values, the quality target `target_db` as a dashed horizontal line, the legend
/// on the right. Returns the picture as sRGB8 RGB pixels, rows top first, [`SIZE_PLOT`] in
/// size. Cost: one raster of that size.
///
/// Errors: the embedded font does not load, or the drawing fails (`ReportError::Plot`).
pub fn error_against_size(
    title: &str,
    lines: &[SizeLine],
    target_db: f64,
) -> Result<Vec<u8>, ReportError> {
    register_font().map_err(plot_err(title))?;
    let (w, h) = SIZE_PLOT;
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw_sizes(&root, title, lines, target_db).map_err(plot_err(title))?;
        root.present().map_err(|e| plot_err(title)(e.to_string()))?;
    }
    Ok(buf)
}

fn draw_sizes<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
    lines: &[SizeLine],
    target_db: f64,
) -> Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (plot, legend) = root.split_horizontally(SIZE_PLOT.0 - SIZE_LEGEND);
    // Points with a positive finite size and a finite PSNR, in order of size, size as log₂.
    let finite = |l: &SizeLine| -> Vec<(f64, f64)> {
        let mut p: Vec<(f64, f64)> = l
            .points
            .iter()
            .filter(|(x, y)| *x > 0.0 && x.is_finite() && y.is_finite())
            .map(|&(x, y)| (x.log2(), y))
            .collect();
        p.sort_by(|a, b| a.0.total_cmp(&b.0));
        p
    };
    let all: Vec<(f64, f64)> = lines.iter().flat_map(finite).collect();
    let (mut x0, mut x1) = all
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.0), b.max(p.0))
        });
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    let (x0, x1) = (x0.floor() - 0.25, x1.ceil() + 0.25);
    let mut ys: Vec<f64> = all.iter().map(|p| p.1).collect();
    if target_db.is_finite() {
        ys.push(target_db);
    }
    let ay = Axis::fit(&ys, false);
    let mut chart = ChartBuilder::on(&plot)
        .caption(title, (FONT, 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, ay.lo..ay.hi)
        .map_err(e)?;
    // Ticks at the powers of two (labelled with the size), none between them.
    let xl = |v: &f64| {
        if (v - v.round()).abs() < 1e-9 {
            format!("{}", v.round().exp2())
        } else {
            String::new()
        }
    };
    let yl = |v: &f64| ay.label(*v);
    axis_style(
        chart
            .configure_mesh()
            .x_desc("screen size (px, log scale)")
            .y_desc("worst PSNR (dB)")
            .x_labels(((x1 - x0).round() as usize + 1) * 4)
            .x_label_formatter(&xl)
            .y_label_formatter(&yl),
    )
    .draw()
    .map_err(e)?;
    let mut entries: Vec<(String, RGBAColor, u32, bool)> = Vec::new();
    if target_db.is_finite() {
        let grey = BLACK.mix(0.6);
        chart
            .draw_series(DashedLineSeries::new(
                vec![(x0, target_db), (x1, target_db)],
                6,
                4,
                grey.stroke_width(1),
            ))
            .map_err(e)?;
        entries.push((format!("target {target_db} dB"), grey, 1, true));
    }
    for (i, line) in lines.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let width = if i == 0 { 6 } else { 2 };
        let pts = finite(line);
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(width)))
            .map_err(e)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|&p| Circle::new(p, width.max(3) + 1, color.filled())),
            )
            .map_err(e)?;
        entries.push((line.name.clone(), color, width, false));
    }
    for (k, (name, color, width, dashed)) in entries.into_iter().enumerate() {
        let y = 48 + 20 * k as i32;
        let style = color.stroke_width(width);
        // A dashed line as two dashes.
        let dashes: &[(i32, i32)] = if dashed {
            &[(8, 15), (21, 28)]
        } else {
            &[(8, 28)]
        };
        for &(a, b) in dashes {
            legend
                .draw(&PathElement::new(vec![(a, y), (b, y)], style))
                .map_err(e)?;
        }
        legend
            .draw(&Text::new(
                name,
                (36, y - 7),
                (FONT, 12).into_font().color(&BLACK),
            ))
            .map_err(e)?;
    }
    Ok(())
}

/// The axes' look every plot here shares: descriptions at 14 px and tick labels at 11 px in
/// the embedded font, no minor grid lines.
fn axis_style<'m, 'a, 'b, X, Y, DB>(
    mesh: &'m mut MeshStyle<'a, 'b, X, Y, DB>,
) -> &'m mut MeshStyle<'a, 'b, X, Y, DB>
where
    X: Ranged,
    Y: Ranged,
    DB: DrawingBackend,
{
    mesh.axis_desc_style((FONT, 14))
        .label_style((FONT, 11))
        .light_line_style(WHITE.mix(0.0))
}

/// One axis: value → drawn coordinate (log10 or identity) and back for tick labels.
#[derive(Clone, Copy)]
struct Axis {
    log: bool,
    lo: f64,
    hi: f64,
}

impl Axis {
    fn fit(values: &[f64], allow_log: bool) -> Self {
        let (mut lo, mut hi) = values
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        let log = allow_log && lo > 0.0 && hi / lo > 20.0;
        let (mut a, mut b) = if log {
            (lo.log10(), hi.log10())
        } else {
            (lo, hi)
        };
        let pad = if b > a {
            0.08 * (b - a)
        } else {
            a.abs().max(1.0) * 0.1
        };
        a -= pad;
        b += pad;
        Self { log, lo: a, hi: b }
    }

    fn to(&self, v: f64) -> f64 {
        if self.log { v.log10() } else { v }
    }

    fn label(&self, t: f64) -> String {
        let v = if self.log { 10f64.powf(t) } else { t };
        let a = v.abs();
        if a == 0.0 {
            "0".into()
        } else if !(1e-3..1e5).contains(&a) {
            format!("{v:.0e}")
        } else if a >= 100.0 {
            format!("{v:.0}")
        } else if a >= 1.0 {
            format!("{v:.3}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        } else {
            format!("{v:.4}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        }
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    r: &RepresentationReport,
) -> Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
    root.fill(&WHITE).map_err(e)?;
    let title = format!("{}: cost against error", r.name);
    let body = root.titled(&title, (FONT, 20)).map_err(e)?;
    let panels = body.split_evenly((1, r.panels.len().max(1)));
    let mut series: Vec<&str> = Vec::new();
    for p in &r.points {
        if !series.contains(&p.series.as_str()) {
            series.push(&p.series);
        }
    }
    for (k, (area, &cost)) in panels.iter().zip(&r.panels).enumerate() {
        draw_panel(area, r, cost, &series, k == 0)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    r: &RepresentationReport,
    cost: Cost,
    series: &[&str],
    legend: bool,
) -> Result<(), String> {
    let e = |x: DrawingAreaErrorKind<DB::ErrorType>| x.to_string();
    let pairs: Vec<(f64, f64)> = r
        .points
        .iter()
        .filter_map(|p| Some((p.cost(cost)?, r.error_of(p)?)))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    let mut xs: Vec<f64> = pairs.iter().map(|p| p.0).collect();
    xs.extend(
        r.references
            .iter()
            .filter(|f| f.cost == cost)
            .map(|f| f.value),
    );
    let ys: Vec<f64> = pairs.iter().map(|p| p.1).collect();
    let ax = Axis::fit(&xs, true);
    let ay = Axis::fit(&ys, !r.uses_psnr);
    let x_desc = format!(
        "{}{}",
        r.cost_label(cost),
        if ax.log { " (log)" } else { "" }
    );
    let y_desc = format!("{}{}", r.error_label, if ay.log { " (log)" } else { "" });
    let mut chart = ChartBuilder::on(area)
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(62)
        .build_cartesian_2d(ax.lo..ax.hi, ay.lo..ay.hi)
        .map_err(e)?;
    // Labels of marks in the right half of the panel end at the mark instead of starting
    // there, so that they stay inside the panel.
    let right_half = |x: f64| x > 0.5 * (ax.lo + ax.hi);
    let anchor = |right: bool| {
        use plotters::style::text_anchor::{HPos, Pos, VPos};
        Pos::new(if right { HPos::Right } else { HPos::Left }, VPos::Top)
    };
    let xl = |v: &f64| ax.label(*v);
    let yl = |v: &f64| ay.label(*v);
    axis_style(
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&xl)
            .y_label_formatter(&yl),
    )
    .draw()
    .map_err(e)?;
    for (i, name) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let mut pts: Vec<(f64, f64)> = r
            .points
            .iter()
            .filter(|p| p.series == *name)
            .filter_map(|p| Some((ax.to(p.cost(cost)?), ay.to(r.error_of(p)?))))
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        if pts.is_empty() && !legend {
            continue;
        }
        // A series with no point on this panel still gets its legend entry (an empty line).
        let front = front(&mut pts, r.uses_psnr);
        let drawn = chart
            .draw_series(LineSeries::new(front.clone(), color.stroke_width(2)))
            .map_err(e)?;
        if legend {
            drawn.label(name.to_string()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2))
            });
        }
        chart
            .draw_series(front.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(e)?;
        chart
            .draw_series(
                pts.iter()
                    .filter(|p| !front.contains(p))
                    .map(|&p| Circle::new(p, 3, color.stroke_width(1))),
            )
            .map_err(e)?;
    }
    // Labels of the claims' lines step down the panel so that close lines stay legible.
    for (k, f) in r.references.iter().filter(|f| f.cost == cost).enumerate() {
        let x = ax.to(f.value);
        if !x.is_finite() {
            continue;
        }
        chart
            .draw_series(DashedLineSeries::new(
                vec![(x, ay.lo), (x, ay.hi)],
                6,
                4,
                BLACK.mix(0.6).stroke_width(1),
            ))
            .map_err(e)?;
        let style = (FONT, 11).into_font().color(&BLACK.mix(0.8));
        chart
            .draw_series(std::iter::once(Text::new(
                f.label.clone(),
                (x, ay.hi - (0.04 + 0.06 * k as f64) * (ay.hi - ay.lo)),
                style.pos(anchor(right_half(x))),
            )))
            .map_err(e)?;
    }
    for p in r.points.iter().filter(|p| p.operating_point.is_some()) {
        let (Some(x), Some(y)) = (p.cost(cost), r.error_of(p)) else {
            continue;
        };
        let at = (ax.to(x), ay.to(y));
        if !(at.0.is_finite() && at.1.is_finite()) {
            continue;
        }
        let label = p.operating_point.clone().unwrap_or_default();
        let right = right_half(at.0);
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 8, BLACK.stroke_width(2))
                    + Text::new(
                        label,
                        (if right { -10 } else { 10 }, -16),
                        (FONT, 12).into_font().color(&BLACK).pos(anchor(right)),
                    ),
            ))
            .map_err(e)?;
    }
    if legend && !series.is_empty() {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .label_font((FONT, 11))
            .position(if r.uses_psnr {
                SeriesLabelPosition::LowerRight
            } else {
                SeriesLabelPosition::UpperRight
            })
            .draw()
            .map_err(e)?;
    }
    Ok(())
}

/// The cost–error front of `pts` (drawn coordinates; cost is `.0`, error `.1`), in order of
/// cost: the points whose error is strictly better than that of every cheaper point, and of every
/// equally cheap point before them once sorted (higher error is better when
/// `higher_is_better`). Sorts `pts` by cost, then from the best error down. Cost: `O(n log n)`.
fn front(pts: &mut [(f64, f64)], higher_is_better: bool) -> Vec<(f64, f64)> {
    let better = |a: f64, b: f64| if higher_is_better { a > b } else { a < b };
    pts.sort_by(|a, b| {
        let by_error = if higher_is_better {
            b.1.total_cmp(&a.1)
        } else {
            a.1.total_cmp(&b.1)
        };
        a.0.total_cmp(&b.0).then(by_error)
    });
    let mut out: Vec<(f64, f64)> = Vec::new();
    for &p in pts.iter() {
        if out.last().is_none_or(|last| better(p.1, last.1)) {
            out.push(p);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{Axis, SIZE_PLOT, SizeLine, error_against_size, front};
    use plotters::style::{Color, Palette, Palette99};

    /// The error-against-size plot draws each line's points in its colour (filled circles of
    /// radius 4 or more, about 50 pixels each, plus the joining line), a line without finite points in
    /// its legend entry only, and leaves NaN and infinite points out without failing.
    #[test]
    fn the_size_plot_draws_every_line_in_its_colour() {
        let lines = [
            SizeLine {
                name: "automatic".into(),
                points: vec![(4.0, 24.0), (16.0, 22.5), (32.0, 23.0), (128.0, 30.0)],
            },
            SizeLine {
                name: "meshes only".into(),
                points: vec![(4.0, 21.0), (f64::NAN, 20.0), (128.0, f64::INFINITY)],
            },
            SizeLine {
                name: "none".into(),
                points: vec![(f64::NAN, f64::NAN)],
            },
        ];
        let rgb = error_against_size("rock", &lines, 22.0).unwrap();
        let (w, h) = SIZE_PLOT;
        assert_eq!(rgb.len(), (w * h * 3) as usize);
        let count = |i: usize| {
            let c = Palette99::pick(i).to_rgba().rgb();
            rgb.chunks_exact(3)
                .filter(|p| (p[0], p[1], p[2]) == c)
                .count()
        };
        let (a, b, none) = (count(0), count(1), count(2));
        assert!(a > 4 * 25 + 100, "{a}");
        assert!(b > 25 && b < a, "{b}");
        // Its legend entry only: a line 21 pixels long, 3 thick.
        assert!(none > 0 && none <= 3 * 21, "{none}");
        // Not a blank picture: the axes, labels and target line are drawn.
        let dark = rgb
            .chunks_exact(3)
            .filter(|p| p.iter().all(|&c| c < 128))
            .count();
        assert!(dark > 1000, "{dark}");
    }

    #[test]
    fn the_front_keeps_the_points_no_cheaper_point_beats() {
        let mut pts = vec![
            (3.0, 12.0),
            (1.0, 10.0),
            (2.0, 9.0),
            (3.0, 11.0),
            (4.0, 12.0),
            (5.0, 13.0),
        ];
        // Higher is better (PSNR): (2, 9) is beaten by the cheaper (1, 10), (3, 11) by the
        // equally cheap (3, 12), (4, 12) only ties it.
        assert_eq!(
            front(&mut pts, true),
            vec![(1.0, 10.0), (3.0, 12.0), (5.0, 13.0)]
        );
        assert_eq!(pts.len(), 6);
        // Lower is better (an error): the cheapest point, then each cheaper error.
        assert_eq!(front(&mut pts, false), vec![(1.0, 10.0), (2.0, 9.0)]);
        assert!(front(&mut [], true).is_empty());
        // Every point of the front beats every cheaper one; every other point is beaten.
        let mut grid: Vec<(f64, f64)> = (0..40)
            .map(|i| (f64::from(i % 7), f64::from((i * 13) % 11)))
            .collect();
        let f = front(&mut grid, true);
        for p in &grid {
            let beaten = grid
                .iter()
                .any(|q| q != p && q.0 <= p.0 && q.1 >= p.1 && (q.0 < p.0 || q.1 > p.1));
            let tied_earlier = f.iter().any(|q| q != p && q.0 <= p.0 && q.1 == p.1);
            assert_eq!(f.contains(p), !beaten && !tied_earlier, "{p:?}");
        }
    }

    #[test]
    fn axes_go_log_only_for_positive_values_spanning_a_factor_above_20() {
        assert!(Axis::fit(&[1.0, 100.0], true).log);
        assert!(!Axis::fit(&[1.0, 10.0], true).log);
        assert!(!Axis::fit(&[0.0, 100.0], true).log);
        assert!(!Axis::fit(&[1.0, 100.0], false).log);
        let a = Axis::fit(&[1.0, 1000.0], true);
        assert!(a.lo < 0.0 && a.hi > 3.0);
        assert_eq!(a.label(2.0), "100");
        // One value: a non-empty range around it.
        let b = Axis::fit(&[5.0], true);
        assert!(b.lo < 5.0 && b.hi > 5.0);
    }
}
