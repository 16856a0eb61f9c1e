//! Printers for [`StudyResults`]: an aligned terminal table, Markdown (for docs), CSV.
//!
//! Numbers use one rule everywhere (terminal, Markdown, viewer): four significant digits,
//! plain decimals from 1e-3 to 1e5, scientific notation outside. CSV keeps full precision.
use crate::results::{keys, MethodResult, Ratio, SceneResult, StudyResults};
use crate::EvalError;
use std::path::Path;

/// Four significant digits; plain between 1e-3 and 1e5, else `1.234e-5`. `–` for non-finite.
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return "–".into();
    }
    if x == 0.0 {
        return "0".into();
    }
    let a = x.abs();
    if (1e-3..1e5).contains(&a) {
        let decimals = (3 - a.log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.3e}")
    }
}

fn fmt_opt(x: Option<f64>) -> String {
    x.map(fmt_num).unwrap_or_else(|| "–".into())
}

/// Seconds with sensible precision for a table (ms below 10 s).
pub fn fmt_seconds(s: f64) -> String {
    if !s.is_finite() {
        "–".into()
    } else if s < 10.0 {
        format!("{s:.3}")
    } else {
        format!("{s:.1}")
    }
}

/// A ratio as `0.392 ± 0.021`, or `0.392` without a standard error.
pub fn fmt_ratio(r: &Ratio) -> String {
    match r.se {
        Some(se) => format!("{} ± {}", fmt_num(r.value), fmt_num(se)),
        None => fmt_num(r.value),
    }
}

/// Display name of a ratio's method key: `ours/IDUW` style.
pub fn ratio_name(r: &Ratio) -> String {
    format!("{}/{}", short_label(&r.numerator), short_label(&r.denominator))
}

/// Short display names of the canonical keys (used in ratio names and headers).
pub fn short_label(key: &str) -> String {
    match key {
        keys::PT => "PT(n)".into(),
        keys::CRN => "CRN(n)".into(),
        keys::AVERAGE => "average".into(),
        keys::IDUW => "IDUW".into(),
        keys::CV => "CV".into(),
        keys::OURS => "ours".into(),
        keys::PT_2N => "PT(2n)".into(),
        other => other.into(),
    }
}

const HEADERS: [&str; 10] =
    ["method", "spp", "relMSE", "± se", "/PT(2n)", "bias²", "variance", "MSE", "render s", "recon s"];

fn rows(scene: &SceneResult, ablation: bool) -> Vec<[String; 10]> {
    let pt2n = scene.method(keys::PT_2N).map(|m| m.relmse_mean).filter(|v| *v > 0.0);
    scene
        .ordered_methods()
        .into_iter()
        .filter(|m| m.ablation == ablation)
        .map(|m: &MethodResult| {
            [
                m.label.clone(),
                if m.spp_total > 0 { m.spp_total.to_string() } else { "?".into() },
                fmt_num(m.relmse_mean),
                fmt_opt(m.relmse_se),
                fmt_opt(pt2n.map(|p| m.relmse_mean / p)),
                fmt_opt(m.bias2),
                fmt_opt(m.variance),
                fmt_num(m.mse_mean),
                fmt_seconds(m.time_seconds.render),
                fmt_seconds(m.time_seconds.reconstruct),
            ]
        })
        .collect()
}

fn scene_title(scene: &SceneResult) -> String {
    let n = scene.spp_per_stream;
    let spp = if n > 0 { format!("{n}+{n} spp, ") } else { String::new() };
    let mut t = format!(
        "{} — {}x{}, {spp}{} seed{}, reference {}",
        scene.name,
        scene.width,
        scene.height,
        scene.seeds,
        if scene.seeds == 1 { "" } else { "s" },
        scene.reference.path
    );
    if let Some(spp) = scene.reference.spp {
        t += &format!(" ({spp} spp)");
    }
    if let Some(noise) = &scene.reference.noise {
        t += &format!(", reference noise relMSE {}", fmt_num(noise.relmse));
    }
    t
}

fn aligned(header: &[&str; 10], rows: &[[String; 10]]) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: Vec<&str>| -> String {
        let mut s = String::new();
        for (i, (c, w)) in cells.iter().zip(&widths).enumerate() {
            let pad = " ".repeat(w - c.chars().count());
            if i == 0 {
                s += &format!("{c}{pad}");
            } else {
                s += &format!("  {pad}{c}");
            }
        }
        s.trim_end().to_string() + "\n"
    };
    let mut out = line(header.to_vec());
    out += &line(widths.iter().map(|w| "-".repeat(*w)).collect::<Vec<_>>().iter().map(|s| s.as_str()).collect());
    for r in rows {
        out += &line(r.iter().map(|s| s.as_str()).collect());
    }
    out
}

/// The terminal table of one scene: title, methods, ablations, headline ratios, warnings.
pub fn terminal_table(scene: &SceneResult) -> String {
    let mut out = scene_title(scene) + "\n\n";
    out += &aligned(&HEADERS, &rows(scene, false));
    let ablations = rows(scene, true);
    if !ablations.is_empty() {
        out += "\nablations\n";
        out += &aligned(&HEADERS, &ablations);
    }
    let ratios = scene.ratios();
    if !ratios.is_empty() {
        out += "\n";
        out += &ratios.iter().map(|r| format!("{} = {}", ratio_name(r), fmt_ratio(r))).collect::<Vec<_>>().join("   ");
        out += "\n";
    }
    for w in &scene.warnings {
        out += &format!("warning: {w}\n");
    }
    out
}

/// Terminal tables of every scene, then geometric-mean ratios when there are several scenes.
pub fn terminal_report(results: &StudyResults) -> String {
    let mut out = results.scenes.iter().map(terminal_table).collect::<Vec<_>>().join("\n");
    if results.scenes.len() > 1 {
        let g = results.geomean_ratios();
        if !g.is_empty() {
            out += &format!(
                "\ngeometric mean over {} scenes: {}\n",
                results.scenes.len(),
                g.iter().map(|r| format!("{} = {}", ratio_name(r), fmt_num(r.value))).collect::<Vec<_>>().join("   ")
            );
        }
    }
    out
}

/// A Markdown table of one scene (methods and ablations), for the project's docs.
pub fn markdown_table(scene: &SceneResult) -> String {
    let mut out = format!("**{}**\n\n", scene_title(scene));
    out += &format!("| {} |\n", HEADERS.join(" | "));
    out += &format!("|{}\n", "---|".repeat(HEADERS.len()));
    for r in rows(scene, false).into_iter().chain(rows(scene, true)) {
        out += &format!("| {} |\n", r.iter().map(|c| c.replace('|', "\\|")).collect::<Vec<_>>().join(" | "));
    }
    let ratios = scene.ratios();
    if !ratios.is_empty() {
        out += "\n";
        out += &ratios.iter().map(|r| format!("{} = {}", ratio_name(r), fmt_ratio(r))).collect::<Vec<_>>().join(", ");
        out += "\n";
    }
    out
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn csv_opt(x: Option<f64>) -> String {
    x.map(|v| v.to_string()).unwrap_or_default()
}

/// One row per scene and method, full precision (shortest round-trip decimal), empty
/// cells for values that need more than one seed.
pub fn to_csv(results: &StudyResults) -> String {
    let mut out = String::from(
        "scene,method,label,spp_per_stream,spp_total,seeds,relmse_mean,relmse_se,bias2,variance,mse_mean,render_seconds,reconstruct_seconds,ablation\n",
    );
    for s in &results.scenes {
        for m in s.ordered_methods() {
            let cells = [
                csv_field(&s.name),
                csv_field(&m.name),
                csv_field(&m.label),
                s.spp_per_stream.to_string(),
                m.spp_total.to_string(),
                s.seeds.to_string(),
                m.relmse_mean.to_string(),
                csv_opt(m.relmse_se),
                csv_opt(m.bias2),
                csv_opt(m.variance),
                m.mse_mean.to_string(),
                m.time_seconds.render.to_string(),
                m.time_seconds.reconstruct.to_string(),
                m.ablation.to_string(),
            ];
            out += &cells.join(",");
            out += "\n";
        }
    }
    out
}

/// Writes [`to_csv`] atomically.
pub fn write_csv(results: &StudyResults, path: &Path, overwrite: bool) -> Result<(), EvalError> {
    let text = to_csv(results);
    cvtrace_streams::atomic::write_atomically(path, overwrite, |tmp| std::fs::write(tmp, text.as_bytes()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_format_keeps_four_significant_digits() {
        assert_eq!(fmt_num(0.003695), "0.003695");
        assert_eq!(fmt_num(0.0424791), "0.04248");
        assert_eq!(fmt_num(1.0), "1.000");
        assert_eq!(fmt_num(123.456), "123.5");
        assert_eq!(fmt_num(0.0), "0");
        assert_eq!(fmt_num(-2.5e-6), "-2.500e-6");
        assert_eq!(fmt_num(3.2e7), "3.200e7");
        assert_eq!(fmt_num(f64::NAN), "–");
        for v in [0.001234567, 0.05, 7.77e-9, 42.0, 99999.0] {
            let back: f64 = fmt_num(v).parse().unwrap();
            assert!((back - v).abs() <= 5e-4 * v.abs(), "{v} -> {}", fmt_num(v));
        }
    }

    #[test]
    fn csv_quotes_fields_that_need_it() {
        assert_eq!(csv_field("plain"), "plain");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    }
}
