//! Convergence plots: relMSE against total spp and against seconds per image, and squared
//! bias against total spp, log-log, one line per estimator, as SVG.
//!
//! Drawn with `plotters`' SVG backend, which writes `<text>` elements and only estimates
//! text extents, so no system fonts are needed. Colours match the viewer (dark theme).
use crate::results::{ConvergencePoint, SceneResult};
use crate::EvalError;
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

const BACKGROUND: RGBColor = RGBColor(0x1d, 0x1f, 0x23);
const FOREGROUND: RGBColor = RGBColor(0xd0, 0xd0, 0xd0);
const GRID: RGBColor = RGBColor(0x34, 0x37, 0x3d);

/// Plot size in pixels.
pub const PLOT_SIZE: (u32, u32) = (720, 440);

/// One line of the plot: a method's points sorted by spp.
struct Line {
    key: String,
    label: String,
    color: RGBColor,
    points: Vec<(f64, f64, Option<f64>)>,
}

/// A method key and its legend position to its legend label and colour.
pub type StyleOf<'a> = &'a dyn Fn(&str, usize) -> (String, [u8; 3]);

/// What a convergence plot puts on its x axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XAxis {
    /// Total samples per pixel.
    Spp,
    /// Mean seconds per image: render of the streams plus reconstruction (points without a
    /// time are left out).
    Seconds,
}

/// What a convergence plot puts on its y axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum YAxis {
    /// relMSE, ± its standard error over seeds.
    RelMse,
    /// Relative squared bias over the seeds: where a biased method's error stops falling with
    /// the samples. Points with no estimate or one at or below 0 (an unbiased method's, noise
    /// about zero) are left out of the log axis.
    Bias2,
}

impl YAxis {
    fn of(self, p: &ConvergencePoint) -> Option<(f64, Option<f64>)> {
        let (v, se) = match self {
            YAxis::RelMse => (p.relmse, p.relmse_se),
            YAxis::Bias2 => (p.bias2?, None),
        };
        (v > 0.0 && v.is_finite()).then_some((v, se))
    }
    fn description(self) -> &'static str {
        match self {
            YAxis::RelMse => "relMSE",
            YAxis::Bias2 => "bias² (relative)",
        }
    }
}

impl XAxis {
    fn of(self, p: &ConvergencePoint) -> Option<f64> {
        match self {
            XAxis::Spp => (p.spp_total > 0).then_some(p.spp_total as f64),
            XAxis::Seconds => p.seconds.filter(|t| *t > 0.0 && t.is_finite()),
        }
    }
    fn description(self) -> &'static str {
        match self {
            XAxis::Spp => "total samples per pixel",
            XAxis::Seconds => "seconds per image (render + reconstruction)",
        }
    }
    fn guide(self) -> &'static str {
        match self {
            XAxis::Spp => "∝ 1/spp",
            XAxis::Seconds => "∝ 1/time",
        }
    }
}

fn lines(points: &[(f64, f64, Option<f64>, &ConvergencePoint)], style_of: StyleOf) -> Vec<Line> {
    // First-appearance order of methods, so the legend follows the results file.
    let mut order: Vec<String> = Vec::new();
    let mut by_method: BTreeMap<String, Vec<(f64, f64, Option<f64>)>> = BTreeMap::new();
    for (x, y, se, p) in points {
        if !by_method.contains_key(&p.method) {
            order.push(p.method.clone());
        }
        by_method.entry(p.method.clone()).or_default().push((*x, *y, *se));
    }
    order
        .into_iter()
        .enumerate()
        .map(|(i, key)| {
            let mut pts = by_method.remove(&key).unwrap_or_default();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (label, c) = style_of(&key, i);
            Line { label, color: RGBColor(c[0], c[1], c[2]), key, points: pts }
        })
        .collect()
}

/// Axis tick text: three significant digits, no trailing zeros (0.01, 2.5e-5, 128).
fn tick(v: f64) -> String {
    let rounded: f64 = format!("{v:.2e}").parse().unwrap_or(v);
    let a = rounded.abs();
    if a == 0.0 || (1e-4..1e6).contains(&a) {
        format!("{rounded}")
    } else {
        format!("{rounded:e}")
    }
}

fn plot_err(e: impl std::fmt::Display) -> EvalError {
    EvalError::invalid("convergence plot", e.to_string())
}

/// The SVG text of a convergence plot against total spp; see [`convergence_svg_against`].
pub fn convergence_svg(points: &[ConvergencePoint], title: &str, style_of: StyleOf) -> Result<String, EvalError> {
    convergence_svg_against(points, XAxis::Spp, title, style_of)
}

/// The SVG text of a relMSE convergence plot with `axis` along x; see [`convergence_svg_of`].
pub fn convergence_svg_against(points: &[ConvergencePoint], axis: XAxis, title: &str, style_of: StyleOf) -> Result<String, EvalError> {
    convergence_svg_of(points, axis, YAxis::RelMse, title, style_of)
}

/// The SVG text of a convergence plot of `y` against `x`. `style_of` maps a method key and its
/// position in the legend to its legend label and colour. For relMSE a dashed grey guide shows
/// the `1/spp` (or `1/time`) slope of an unbiased Monte Carlo estimator.
pub fn convergence_svg_of(points: &[ConvergencePoint], axis: XAxis, y: YAxis, title: &str, style_of: StyleOf) -> Result<String, EvalError> {
    let valid: Vec<(f64, f64, Option<f64>, &ConvergencePoint)> =
        points.iter().filter_map(|p| Some((axis.of(p)?, y.of(p)?, p))).map(|(x, (v, se), p)| (x, v, se, p)).collect();
    if valid.is_empty() {
        let need = match axis {
            XAxis::Spp => "spp > 0",
            XAxis::Seconds => "seconds > 0",
        };
        return Err(EvalError::invalid("convergence plot", format!("no point with {need} and a finite {} > 0", y.description())));
    }
    let lines = lines(&valid, style_of);
    let xs = valid.iter().map(|(x, ..)| *x);
    let (xmin, xmax) = xs.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
    let lows = valid.iter().map(|(_, v, se, _)| (v - se.unwrap_or(0.0)).max(v * 0.5));
    let highs = valid.iter().map(|(_, v, se, _)| v + se.unwrap_or(0.0));
    let ymin = lows.fold(f64::MAX, f64::min);
    let ymax = highs.fold(f64::MIN, f64::max);
    let (x0, x1) = (xmin / 1.3, xmax * 1.3);
    let (y0, y1) = (ymin / 1.6, ymax * 1.6);

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, PLOT_SIZE).into_drawing_area();
        root.fill(&BACKGROUND).map_err(plot_err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 20).into_font().color(&FOREGROUND))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(78)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .x_desc(axis.description())
            .y_desc(y.description())
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .axis_style(FOREGROUND.mix(0.8))
            .bold_line_style(GRID)
            .light_line_style(GRID.mix(0.4))
            .label_style(("sans-serif", 13).into_font().color(&FOREGROUND))
            .axis_desc_style(("sans-serif", 14).into_font().color(&FOREGROUND))
            .draw()
            .map_err(plot_err)?;

        // 1/spp (1/time) guide through the first point of the first line (PT when present).
        if let Some(&(sx, sy, _)) = lines.first().and_then(|l| l.points.first()).filter(|_| y == YAxis::RelMse) {
            let guide = [(x0, sy * sx / x0), (x1, sy * sx / x1)];
            chart
                .draw_series(DashedLineSeries::new(guide, 6, 6, RGBColor(0x70, 0x74, 0x7c).stroke_width(1)))
                .map_err(plot_err)?
                .label(axis.guide())
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], RGBColor(0x70, 0x74, 0x7c)));
        }
        for line in &lines {
            let color = line.color;
            chart
                .draw_series(LineSeries::new(line.points.iter().map(|p| (p.0, p.1)), color.stroke_width(2)))
                .map_err(plot_err)?
                .label(&line.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2)));
            chart.draw_series(line.points.iter().map(|p| Circle::new((p.0, p.1), 3, color.filled()))).map_err(plot_err)?;
            // ± one standard error, clipped below to stay on the log axis.
            chart
                .draw_series(
                    line.points
                        .iter()
                        .filter_map(|p| p.2.map(|se| (p.0, p.1, se)))
                        .map(|(x, y, se)| PathElement::new(vec![(x, (y - se).max(y * 0.5)), (x, y + se)], color.stroke_width(1))),
                )
                .map_err(plot_err)?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(BACKGROUND.mix(0.9))
            .border_style(GRID)
            .label_font(("sans-serif", 13).into_font().color(&FOREGROUND))
            .draw()
            .map_err(plot_err)?;
        root.present().map_err(plot_err)?;
    }
    // Keep the keys findable (e.g. by tests and scripts) without relying on drawing order.
    let keys: Vec<&str> = lines.iter().map(|l| l.key.as_str()).collect();
    Ok(svg.replacen("<svg ", &format!("<svg data-methods=\"{}\" ", keys.join(" ")), 1))
}

/// Writes the convergence plot of `scene` against spp atomically; `Ok(false)` when it has no points.
pub fn write_convergence_svg(scene: &SceneResult, path: &Path, overwrite: bool) -> Result<bool, EvalError> {
    write_convergence_svg_against(scene, XAxis::Spp, path, overwrite)
}

/// Writes the relMSE convergence plot of `scene` with `axis` along x atomically; see
/// [`write_convergence_svg_of`].
pub fn write_convergence_svg_against(scene: &SceneResult, axis: XAxis, path: &Path, overwrite: bool) -> Result<bool, EvalError> {
    write_convergence_svg_of(scene, axis, YAxis::RelMse, path, overwrite)
}

/// Writes the convergence plot of `y` against `axis` of `scene` atomically; `Ok(false)` when it
/// has no points (against time: none with a recorded time, as in results of older studies; of
/// bias²: none with a positive estimate).
pub fn write_convergence_svg_of(scene: &SceneResult, axis: XAxis, y: YAxis, path: &Path, overwrite: bool) -> Result<bool, EvalError> {
    if scene.convergence.is_empty()
        || (axis == XAxis::Seconds && scene.convergence.iter().all(|p| axis.of(p).is_none()))
        || (y == YAxis::Bias2 && scene.convergence.iter().all(|p| y.of(p).is_none()))
    {
        return Ok(false);
    }
    let style_of = |k: &str, i: usize| {
        (scene.method(k).map(|m| m.label.clone()).unwrap_or_else(|| k.to_string()), crate::palette::method_colour(scene, k, i))
    };
    let quantity = match y {
        YAxis::RelMse => "relMSE",
        YAxis::Bias2 => "bias²",
    };
    let title = match axis {
        XAxis::Spp => format!("{}: {quantity} vs spp", scene.name),
        XAxis::Seconds => format!("{}: {quantity} vs time", scene.name),
    };
    let svg = convergence_svg_of(&scene.convergence, axis, y, &title, &style_of)
        .map_err(|e| EvalError::invalid(format!("scene `{}`", scene.name), e.to_string()))?;
    cvtrace_streams::atomic::write_atomically(path, overwrite, |tmp| std::fs::write(tmp, svg.as_bytes()))?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pts() -> Vec<ConvergencePoint> {
        let mut v = Vec::new();
        for (m, c) in [("pt", 1.0), ("ours", 0.2)] {
            for spp in [16u32, 64, 256] {
                v.push(ConvergencePoint {
                    method: m.into(),
                    spp_total: spp,
                    relmse: c / spp as f64,
                    relmse_se: Some(0.1 * c / spp as f64),
                    seconds: Some(0.01 * spp as f64),
                    // ours with a bias floor, pt unbiased (its estimate about zero).
                    bias2: Some(if m == "pt" { -1e-6 } else { 1e-4 }),
                });
            }
        }
        v
    }

    #[test]
    fn svg_has_lines_labels_and_text_without_system_fonts() {
        let style = |k: &str, _| (format!("label-{k}"), if k == "ours" { [0x59, 0xd9, 0x8e] } else { [0xe1, 0x57, 0x59] });
        let svg = convergence_svg(&pts(), "cbox: relMSE vs spp", &style).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..100]);
        assert!(svg.contains("data-methods=\"pt ours\""));
        assert!(svg.contains("cbox: relMSE vs spp"));
        assert!(svg.contains("label-pt") && svg.contains("label-ours"));
        assert!(svg.contains("total samples per pixel") && svg.contains("relMSE"));
        assert!(svg.contains("<text"), "text must be emitted as SVG text");
        // One polyline per method plus the guide; a point per sample.
        assert!(svg.matches("<polyline").count() >= 2, "{svg}");
        assert!(svg.matches("<circle").count() >= 6);
        assert!(svg.contains("#59D98E") || svg.contains("#59d98e"), "ours keeps the colour it was given");
    }

    #[test]
    fn time_plot_puts_seconds_along_x_and_skips_points_without_one() {
        let style = |k: &str, _| (format!("label-{k}"), [0x80; 3]);
        let mut points = pts();
        points[0].seconds = None;
        let svg = convergence_svg_against(&points, XAxis::Seconds, "cbox: relMSE vs time", &style).unwrap();
        assert!(svg.contains("seconds per image") && svg.contains("∝ 1/time") && svg.contains("relMSE vs time"), "{svg}");
        assert!(!svg.contains("total samples per pixel"));
        assert_eq!(svg.matches("<circle").count(), 5, "the point without a time is not drawn");
        // Results of a study that recorded no times have no time plot.
        for p in points.iter_mut() {
            p.seconds = None;
        }
        assert!(convergence_svg_against(&points, XAxis::Seconds, "t", &style).is_err());
    }

    #[test]
    fn the_bias_plot_shows_the_methods_with_a_positive_estimate_and_no_slope_guide() {
        let style = |k: &str, _i: usize| (k.to_uppercase(), [200, 100, 50]);
        let svg = convergence_svg_of(&pts(), XAxis::Spp, YAxis::Bias2, "cbox: bias² vs spp", &style).unwrap();
        assert!(svg.contains("data-methods=\"ours\""), "pt's negative estimates are left out");
        assert!(svg.contains("bias² (relative)") && !svg.contains("∝ 1/spp"), "{svg}");
        let unbiased: Vec<ConvergencePoint> = pts().into_iter().filter(|p| p.method == "pt").collect();
        assert!(convergence_svg_of(&unbiased, XAxis::Spp, YAxis::Bias2, "t", &style).is_err());
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(0.01), "0.01");
        assert_eq!(tick(0.010000000002), "0.01");
        assert_eq!(tick(128.0), "128");
        assert_eq!(tick(2.5e-5), "2.5e-5");
        assert_eq!(tick(0.123456), "0.123");
    }

    #[test]
    fn every_decade_in_range_is_labelled() {
        // relMSE from 2e-4 to 0.3 over 16 to 4096 spp: the y axis spans three decades and more,
        // and each of them must carry a label, as must the x axis' 100 and 1000.
        let points: Vec<ConvergencePoint> = [(16u32, 0.3), (64, 0.05), (256, 0.01), (1024, 0.002), (4096, 2e-4)]
            .iter()
            .map(|&(spp, r)| ConvergencePoint {
                method: "pt".into(),
                spp_total: spp,
                relmse: r,
                relmse_se: None,
                seconds: None,
                bias2: None,
            })
            .collect();
        let svg = convergence_svg(&points, "t", &|k, _| (k.to_string(), [0; 3])).unwrap();
        let labels: Vec<&str> =
            svg.split("<text").filter_map(|t| t.split('>').nth(1)).map(|t| t.split('<').next().unwrap_or("").trim()).collect();
        for want in ["0.001", "0.01", "0.1", "100", "1000"] {
            assert!(labels.contains(&want), "no axis label {want}; labels {labels:?}");
        }
    }

    #[test]
    fn invalid_points_are_rejected_not_drawn() {
        let bad = vec![ConvergencePoint { method: "pt".into(), spp_total: 0, relmse: 1.0, relmse_se: None, seconds: None, bias2: None }];
        assert!(convergence_svg(&bad, "t", &|k, _| (k.to_string(), [0; 3])).is_err());
    }
}
