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

/// Display name of a ratio in `scene`: `ours/IDUW` style, from the methods' short labels.
pub fn ratio_name(r: &Ratio, scene: &SceneResult) -> String {
    format!("{}/{}", scene.short_label(&r.numerator), scene.short_label(&r.denominator))
}

const HEADERS: [&str; 10] = ["method", "spp", "relMSE", "± se", "/PT(2n)", "bias²", "variance", "MSE", "render s", "recon s"];

/// Where the HDR-FLIP mean and its standard error go in [`HEADERS`]: after MSE, before the times.
const FLIP_AT: usize = 8;

/// The column headers of `scene`'s tables: FLIP's only when some method has it (results of
/// older studies do not).
fn headers(scene: &SceneResult) -> Vec<&'static str> {
    let mut h = HEADERS.to_vec();
    if has_flip(scene) {
        h.splice(FLIP_AT..FLIP_AT, ["FLIP", "± se"]);
    }
    h
}

fn has_flip(scene: &SceneResult) -> bool {
    scene.methods.iter().any(|m| m.flip_mean.is_some())
}

fn rows(scene: &SceneResult, ablation: bool) -> Vec<Vec<String>> {
    let pt2n = scene.method(keys::PT_2N).map(|m| m.relmse_mean).filter(|v| *v > 0.0);
    let flip = has_flip(scene);
    scene
        .ordered_methods()
        .into_iter()
        .filter(|m| m.ablation == ablation)
        .map(|m: &MethodResult| {
            let mut row = vec![
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
            ];
            if flip {
                row.splice(FLIP_AT..FLIP_AT, [fmt_opt(m.flip_mean), fmt_opt(m.flip_se)]);
            }
            row
        })
        .collect()
}

pub(crate) fn scene_title(scene: &SceneResult) -> String {
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

pub(crate) fn aligned(header: &[&str], rows: &[Vec<String>]) -> String {
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
    let headers = headers(scene);
    out += &aligned(&headers, &rows(scene, false));
    let ablations = rows(scene, true);
    if !ablations.is_empty() {
        out += "\nablations\n";
        out += &aligned(&headers, &ablations);
    }
    let ratios = scene.ratios();
    if !ratios.is_empty() {
        out += "\n";
        out += &ratios.iter().map(|r| format!("{} = {}", ratio_name(r, scene), fmt_ratio(r))).collect::<Vec<_>>().join("   ");
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
                "\ngeometric mean over {}: {}\n",
                geomean_scenes(results),
                g.iter()
                    .map(|r| format!("{}/{} = {}", results.short_label(&r.numerator), results.short_label(&r.denominator), fmt_ratio(r)))
                    .collect::<Vec<_>>()
                    .join("   ")
            );
        }
    }
    out
}

/// "N scenes", or "k of N scenes" when some scenes define none of the headline ratios (every
/// method's relMSE is 0 there, say) and so do not enter the geometric means.
fn geomean_scenes(results: &StudyResults) -> String {
    let n = results.scenes.len();
    let k = results.scenes.iter().filter(|s| !s.ratios().is_empty()).count();
    if k == n {
        format!("{n} scenes")
    } else {
        format!("{k} of {n} scenes")
    }
}

/// A Markdown table of one scene (methods and ablations), for the project's docs.
pub fn markdown_table(scene: &SceneResult) -> String {
    let mut out = format!("**{}**\n\n", md_text(&scene_title(scene)));
    let headers = headers(scene);
    out += &md_row(&headers.iter().map(|h| h.to_string()).collect::<Vec<_>>());
    out += &format!("|{}\n", "---|".repeat(headers.len()));
    for mut r in rows(scene, false).into_iter().chain(rows(scene, true)) {
        r[0] = md_text(&r[0]);
        out += &md_row(&r);
    }
    let ratios = scene.ratios();
    if !ratios.is_empty() {
        out += "\n";
        out += &ratios.iter().map(|r| format!("{} = {}", ratio_name(r, scene), fmt_ratio(r))).collect::<Vec<_>>().join(", ");
        out += "\n";
    }
    out
}

/// Cross-scene Markdown for the project's results page: one row per scene with every method's
/// relMSE, the headline ratios and the paper's own PT(2n) convention (PT(n)/2), a geometric-mean
/// row; then the ablations as relative changes of `ours`; then each scene's full table.
pub fn markdown_summary(results: &StudyResults) -> String {
    let methods = main_method_keys(results);
    let headline = results.headline();
    let focus = headline.first().map(|(a, _)| a.clone());
    let mut out = String::new();
    let mut header: Vec<String> = vec!["scene".into()];
    header.extend(methods.iter().map(|k| results.short_label(k)));
    header.extend(headline.iter().map(|(a, b)| format!("{}/{}", results.short_label(a), results.short_label(b))));
    header.push(format!("{}/({}/2)", focus.as_deref().map(|f| results.short_label(f)).unwrap_or_default(), results.short_label(keys::PT)));
    header.push("ref. noise ÷ best".into());
    out += &md_row(&header);
    out += &format!("|{}\n", "---|".repeat(header.len()));
    let mut paper_logs = Vec::new();
    for s in &results.scenes {
        let mut row = vec![format!("{} ({}+{})", md_text(&s.name), s.spp_per_stream, s.spp_per_stream)];
        row.extend(methods.iter().map(|k| s.method(k).map(|m| fmt_num(m.relmse_mean)).unwrap_or_else(|| "–".into())));
        row.extend(headline.iter().map(|(a, b)| s.ratio(a, b).map(|r| fmt_ratio(&r)).unwrap_or_else(|| "–".into())));
        let paper = focus.as_deref().and_then(|f| paper_pt2n_ratio(s, f));
        if let Some(p) = paper {
            paper_logs.push(p.ln());
        }
        row.push(fmt_opt(paper));
        row.push(fmt_opt(s.reference.noise.as_ref().zip(s.best_relmse()).map(|(n, b)| n.relmse / b)));
        out += &md_row(&row);
    }
    if results.scenes.len() > 1 {
        let mut row = vec![format!("**geometric mean ({})**", geomean_scenes(results))];
        row.extend(methods.iter().map(|_| String::new()));
        let g = results.geomean_ratios();
        row.extend(headline.iter().map(|(a, b)| {
            g.iter().find(|r| r.numerator == *a && r.denominator == *b).map(|r| format!("**{}**", fmt_ratio(r))).unwrap_or_default()
        }));
        row.push(if paper_logs.is_empty() {
            String::new()
        } else {
            format!("**{}**", fmt_num((paper_logs.iter().sum::<f64>() / paper_logs.len() as f64).exp()))
        });
        row.push(String::new());
        out += &md_row(&row);
    }
    let ablations = ablation_keys(results, focus.as_deref().unwrap_or_default());
    if !ablations.is_empty() {
        out += "\nAblations: relMSE change against the estimator each varies, with its study settings, on the same scene and seeds.\n\n";
        let mut header = vec!["scene".to_string()];
        header.extend(ablations.iter().map(|(_, label, _)| md_text(label)));
        out += &md_row(&header);
        out += &format!("|{}\n", "---|".repeat(header.len()));
        let mut logs = vec![Vec::new(); ablations.len()];
        for s in &results.scenes {
            let mut row = vec![md_text(&s.name)];
            for (j, (key, _, base)) in ablations.iter().enumerate() {
                let r = s.ratio(key, base);
                if let Some(r) = &r {
                    logs[j].push(r.value.ln());
                }
                row.push(r.map(|r| fmt_change(r.value)).unwrap_or_else(|| "–".into()));
            }
            out += &md_row(&row);
        }
        if results.scenes.len() > 1 {
            let mut row = vec!["**geometric mean**".to_string()];
            row.extend(logs.iter().map(|l| {
                if l.is_empty() {
                    String::new()
                } else {
                    format!("**{}**", fmt_change((l.iter().sum::<f64>() / l.len() as f64).exp()))
                }
            }));
            out += &md_row(&row);
        }
    }
    for s in &results.scenes {
        out += "\n";
        out += &markdown_table(s);
    }
    out
}

/// focus ÷ (PT(n)/2): the paper's PT(2n) column is half of PT(n)'s relMSE, not a render.
fn paper_pt2n_ratio(scene: &SceneResult, focus: &str) -> Option<f64> {
    let (f, pt) = (scene.method(focus)?, scene.method(keys::PT)?);
    (pt.relmse_mean > 0.0).then(|| f.relmse_mean / (pt.relmse_mean / 2.0))
}

/// Every scene's non-ablation method keys, each once, in first-seen order.
fn main_method_keys(results: &StudyResults) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for m in results.scenes.iter().flat_map(|s| s.methods.iter()).filter(|m| !m.ablation) {
        if !out.contains(&m.name) {
            out.push(m.name.clone());
        }
    }
    out
}

/// Ablation method keys, labels and the key each varies (`focus` where the file does not
/// say), in first-seen order over all scenes.
fn ablation_keys(results: &StudyResults, focus: &str) -> Vec<(String, String, String)> {
    let mut out: Vec<(String, String, String)> = Vec::new();
    for m in results.scenes.iter().flat_map(|s| s.methods.iter()).filter(|m| m.ablation) {
        if !out.iter().any(|(k, _, _)| *k == m.name) {
            out.push((m.name.clone(), m.label.clone(), m.base.clone().unwrap_or_else(|| focus.to_string())));
        }
    }
    out
}

/// A ratio as a signed percentage change: 1.24 → `+24%`.
fn fmt_change(ratio: f64) -> String {
    if !ratio.is_finite() {
        return "–".into();
    }
    format!("{:+.0}%", (ratio - 1.0) * 100.0)
}

/// Text from a results file (scene names, labels, paths) as literal Markdown: one line, with
/// the characters that would start emphasis, code, links or HTML escaped.
fn md_text(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\r' | '\n' => out.push(' '),
            '\\' | '`' | '*' | '_' | '[' | ']' => {
                out.push('\\');
                out.push(c);
            }
            '<' => out += "&lt;",
            '>' => out += "&gt;",
            '&' => out += "&amp;",
            _ => out.push(c),
        }
    }
    out
}

fn md_row(cells: &[String]) -> String {
    format!("| {} |\n", cells.iter().map(|c| c.replace('|', "\\|")).collect::<Vec<_>>().join(" | "))
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Shortest round-trip text of `x`: plain decimal for ordinary magnitudes, scientific notation
/// (`1.5e-9`) outside them, where plain decimal would run to dozens of digits. Spreadsheets and
/// CSV readers parse both.
fn csv_num(x: f64) -> String {
    let a = x.abs();
    if x == 0.0 || !x.is_finite() || (1e-4..1e15).contains(&a) {
        x.to_string()
    } else {
        format!("{x:e}")
    }
}

fn csv_opt(x: Option<f64>) -> String {
    x.map(csv_num).unwrap_or_default()
}

/// One row per scene and method, full precision (shortest round-trip), empty cells for values
/// that need more than one seed (and for FLIP where the results have none). FLIP's columns come
/// last, so readers of the older columns by position still find them.
pub fn to_csv(results: &StudyResults) -> String {
    let mut out = String::from(
        "scene,method,label,spp_per_stream,spp_total,seeds,relmse_mean,relmse_se,bias2,variance,mse_mean,render_seconds,reconstruct_seconds,ablation,flip_mean,flip_se\n",
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
                csv_num(m.relmse_mean),
                csv_opt(m.relmse_se),
                csv_opt(m.bias2),
                csv_opt(m.variance),
                csv_num(m.mse_mean),
                csv_num(m.time_seconds.render),
                csv_num(m.time_seconds.reconstruct),
                m.ablation.to_string(),
                csv_opt(m.flip_mean),
                csv_opt(m.flip_se),
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
    fn csv_numbers_round_trip_and_stay_short() {
        for v in [0.0, 1.0, 0.25, 1e-4, 3.0e-7, 1.234_567_890_123e-12, 6.02e23, 123456.789, f64::MIN_POSITIVE, -4.5e-9] {
            let text = csv_num(v);
            assert_eq!(text.parse::<f64>().unwrap(), v, "{text}");
            assert!(text.len() <= 24, "{v}: {text}");
        }
        assert_eq!(csv_num(0.5), "0.5");
        assert_eq!(csv_num(2.5e-9), "2.5e-9");
    }

    /// A scene whose methods have per-seed relMSE values (mean and se filled in from them).
    fn seeded_scene(name: &str, per_seed: &[(&str, [f64; 4])]) -> SceneResult {
        let mut sc = scene(name, &per_seed.iter().map(|(k, _)| (*k, 0.0, false)).collect::<Vec<_>>());
        for (m, (_, v)) in sc.methods.iter_mut().zip(per_seed) {
            let mean = v.iter().sum::<f64>() / 4.0;
            let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / 3.0;
            (m.relmse_mean, m.relmse_se, m.relmse_per_seed) = (mean, Some((var / 4.0).sqrt()), v.to_vec());
        }
        sc.seeds = 4;
        sc
    }

    #[test]
    fn ratio_errors_pair_shared_inputs_only_and_carry_into_the_geometric_mean() {
        // ours and IDUW move together over the seeds (they read the same streams); PT(2n) is
        // a render of its own.
        let a = seeded_scene(
            "a",
            &[("ours", [0.10, 0.12, 0.11, 0.13]), ("iduw", [0.20, 0.25, 0.21, 0.26]), ("pt2n", [0.30, 0.28, 0.33, 0.29])],
        );
        let b = seeded_scene(
            "b",
            &[("ours", [0.05, 0.04, 0.06, 0.05]), ("iduw", [0.09, 0.10, 0.08, 0.11]), ("pt2n", [0.20, 0.21, 0.19, 0.22])],
        );
        let unpaired = |s: &SceneResult, x: &str, y: &str| {
            let (p, q) = (s.method(x).unwrap(), s.method(y).unwrap());
            p.relmse_mean / q.relmse_mean
                * ((p.relmse_se.unwrap() / p.relmse_mean).powi(2) + (q.relmse_se.unwrap() / q.relmse_mean).powi(2)).sqrt()
        };
        let r = a.ratio("ours", "iduw").unwrap();
        assert!(r.se.unwrap() < 0.6 * unpaired(&a, "ours", "iduw"), "pairing must remove the shared seed noise: {r:?}");
        let r = a.ratio("ours", "pt2n").unwrap();
        assert!((r.se.unwrap() - unpaired(&a, "ours", "pt2n")).abs() < 1e-15, "PT(2n) is independent: {r:?}");
        let results = StudyResults::new(vec![a.clone(), b.clone()]);
        for g in results.geomean_ratios() {
            let (ra, rb) = (a.ratio(&g.numerator, &g.denominator).unwrap(), b.ratio(&g.numerator, &g.denominator).unwrap());
            assert!((g.value - (ra.value * rb.value).sqrt()).abs() < 1e-12);
            let expect = g.value * ((ra.se.unwrap() / ra.value).powi(2) + (rb.se.unwrap() / rb.value).powi(2)).sqrt() / 2.0;
            assert!((g.se.unwrap() - expect).abs() < 1e-12, "{g:?} vs {expect}");
        }
        assert!(
            terminal_report(&results).contains("geometric mean over 2 scenes: ours/IDUW = ") && terminal_report(&results).contains(" ± ")
        );
    }

    fn scene(name: &str, relmse: &[(&str, f64, bool)]) -> SceneResult {
        SceneResult {
            name: name.into(),
            width: 4,
            height: 4,
            spp_per_stream: 96,
            seeds: 1,
            reference: crate::results::ReferenceInfo { path: "ref.exr".into(), spp: None, image: None, noise: None, values: None },
            methods: relmse
                .iter()
                .map(|&(k, v, ablation)| MethodResult {
                    name: k.into(),
                    label: format!("label {k}"),
                    spp_total: 192,
                    relmse_mean: v,
                    relmse_se: None,
                    bias2: None,
                    variance: None,
                    predicted_variance: None,
                    predicted_variance_per_seed: Vec::new(),
                    image_mean_offset: None,
                    image_mean_offset_se: None,
                    mse_mean: v,
                    relmse_per_seed: vec![v],
                    time_seconds: Default::default(),
                    image: None,
                    error_map: None,
                    difference_map: None,
                    flip_mean: None,
                    flip_se: None,
                    flip_per_seed: Vec::new(),
                    flip_map: None,
                    values: None,
                    ablation,
                    base: ablation.then(|| "ours".into()),
                    // The short labels travel with the results: the tables print these, not the keys.
                    short: if k == "iduw" { "IDUW".into() } else { String::new() },
                    colour: None,
                    settings: Vec::new(),
                    diagnostics: Vec::new(),
                })
                .collect(),
            convergence: Vec::new(),
            error_map_scale: None,
            difference_scale: None,
            flip: None,
            warnings: Vec::new(),
            headline: crate::results::paper_headline(),
            render: Vec::new(),
        }
    }

    #[test]
    fn markdown_summary_has_a_row_per_scene_and_geometric_means() {
        let a = scene(
            "a",
            &[
                ("pt", 0.4, false),
                ("pt2n", 0.2, false),
                ("iduw", 0.1, false),
                ("cv", 0.08, false),
                ("ours", 0.05, false),
                ("ours-window", 0.06, true),
            ],
        );
        let b = scene(
            "b",
            &[
                ("pt", 0.2, false),
                ("pt2n", 0.1, false),
                ("iduw", 0.02, false),
                ("cv", 0.04, false),
                ("ours", 0.01, false),
                ("ours-window", 0.015, true),
            ],
        );
        let md = markdown_summary(&StudyResults::new(vec![a, b]));
        assert!(md.contains("| a (96+96) |"), "{md}");
        assert!(md.contains("| b (96+96) |"), "{md}");
        // ours/IDUW: 0.5 and 0.5 → 0.5; ours/CV: 0.625 and 0.25 → sqrt(0.15625); ours/PT(2n): 0.25, 0.1.
        let geo = md.lines().find(|l| l.contains("geometric mean (2 scenes)")).expect("geomean row");
        assert!(geo.contains("**0.5000**"), "{geo}");
        assert!(geo.contains(&format!("**{}**", fmt_num(0.15625f64.sqrt()))), "{geo}");
        assert!(geo.contains(&format!("**{}**", fmt_num((0.25f64 * 0.1).sqrt()))), "{geo}");
        // The paper's convention, ours / (PT(n)/2): 0.25 and 0.1 again here.
        assert!(md.lines().find(|l| l.starts_with("| a ")).unwrap().ends_with("| 0.2500 | – |"), "{md}");
        // Ablations: +20% and +50%, geometric mean sqrt(1.2·1.5) − 1 = +34%.
        let abl = md.lines().find(|l| l.starts_with("| a |")).expect("ablation row");
        assert!(abl.contains("+20%"), "{abl}");
        assert!(md.contains("**+34%**"), "{md}");
        // Per-scene tables follow.
        assert_eq!(md.matches("**a — ").count(), 1, "{md}");
    }

    #[test]
    fn markdown_keeps_names_literal_and_counts_the_scenes_in_the_means() {
        let odd = "x</td><script>|*y*\nz_";
        let a = scene(odd, &[("pt", 0.4, false), ("pt2n", 0.2, false), ("iduw", 0.1, false), ("cv", 0.08, false), ("ours", 0.05, false)]);
        // Every relMSE 0: no ratio is defined, so this scene is not in the geometric means.
        let void =
            scene("void", &[("pt", 0.0, false), ("pt2n", 0.0, false), ("iduw", 0.0, false), ("cv", 0.0, false), ("ours", 0.0, false)]);
        let md = markdown_summary(&StudyResults::new(vec![a, void]));
        let escaped = "x&lt;/td&gt;&lt;script&gt;\\|\\*y\\* z\\_";
        assert!(md.contains(&format!("| {escaped} (96+96) |")), "{md}");
        assert!(!md.contains("<script>") && md.lines().all(|l| !l.starts_with("z_")), "{md}");
        assert!(md.contains("geometric mean (1 of 2 scenes)"), "{md}");
    }

    #[test]
    fn flip_columns_appear_only_with_flip_values() {
        let mut sc = scene("a", &[("pt", 0.4, false), ("ours", 0.05, false)]);
        let plain = terminal_table(&sc);
        assert!(!plain.contains("FLIP"), "{plain}");
        assert!(to_csv(&StudyResults::new(vec![sc.clone()])).lines().nth(1).unwrap().ends_with(",false,,"));
        sc.methods[1].flip_mean = Some(0.123456);
        sc.methods[1].flip_se = Some(0.0042);
        let t = terminal_table(&sc);
        let header = t.lines().find(|l| l.starts_with("method")).unwrap();
        let cols: Vec<&str> = header.split_whitespace().collect();
        assert_eq!(&cols[8..12], ["MSE", "FLIP", "±", "se"], "{header}");
        let ours = t.lines().find(|l| l.starts_with("label ours")).unwrap();
        assert!(ours.contains(" 0.1235 ") && ours.contains(" 0.004200 "), "{ours}");
        assert!(t.lines().find(|l| l.starts_with("label pt")).unwrap().matches('–').count() >= 2);
        assert!(markdown_table(&sc).contains("| MSE | FLIP | ± se | render s |"));
        let csv = to_csv(&StudyResults::new(vec![sc]));
        assert!(csv.lines().next().unwrap().ends_with(",ablation,flip_mean,flip_se"));
        assert!(csv.lines().nth(2).unwrap().ends_with(",false,0.123456,0.0042"), "{csv}");
    }

    #[test]
    fn csv_quotes_fields_that_need_it() {
        assert_eq!(csv_field("plain"), "plain");
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    }
}
