//! The static comparison viewer: one self-contained folder that works offline from file://.
//!
//! ```text
//! out/index.html  viewer.css  viewer.js     the page (fixed assets, built into the crate)
//! out/data.js                                window.CVTRACE_DATA = { results, per-scene view data }
//! out/images/<scene>/*.png                  copies of the study's previews, relMSE, difference and FLIP maps
//! out/images/<scene>/pixels.js               linear values for the pixel readout (see `pixels`)
//! out/plots/<scene>.svg  <scene>.time.svg    convergence plots against spp and against time
//! out/plots/<scene>.bias.svg                squared bias against spp
//! out/colorbar.png  colorbar-diff.png  colorbar-flip.png  results.json  results.csv
//! out/.cvtrace-report                        the images and plots this report wrote (one per line)
//! ```
//! The page builds itself from data.js (a plain script, so no server or fetch is needed);
//! every number it shows comes from the results tree, formatted like the terminal table.
use crate::difference::write_difference_colorbar_png;
use crate::falsecolor::write_colorbar_png;
use crate::flip::write_flip_colorbar_png;
use crate::palette::{hex, method_colour};
use crate::pixels::read_values_exr;
use crate::plots::{write_convergence_svg_of, XAxis, YAxis};
use crate::results::{Ratio, SceneResult, StudyResults};
use crate::table::write_csv;
use crate::EvalError;
use cvtrace_streams::atomic::write_atomically;
use cvtrace_streams::output_lock::{lock_path_for, OutputLock};
use serde::Serialize;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

const INDEX_HTML: &str = include_str!("../assets/index.html");
const VIEWER_CSS: &str = include_str!("../assets/viewer.css");
const VIEWER_JS: &str = include_str!("../assets/viewer.js");

/// Options of [`write_report`].
#[derive(Clone, Debug)]
pub struct ReportOptions {
    /// Shown in the page title.
    pub title: String,
    /// Write into an `out_dir` that is not empty (replacing an earlier report); otherwise refuse.
    pub overwrite: bool,
}

impl Default for ReportOptions {
    fn default() -> Self {
        ReportOptions { title: "cvtrace study".into(), overwrite: false }
    }
}

/// What data.js holds besides the results.
#[derive(Serialize)]
struct ViewerData<'a> {
    title: &'a str,
    results: &'a StudyResults,
    scenes: Vec<ViewerScene>,
    geomean_ratios: Vec<Ratio>,
    colorbar: &'a str,
    difference_colorbar: &'a str,
    flip_colorbar: &'a str,
    files: BTreeMap<&'a str, &'a str>,
}

#[derive(Serialize)]
struct ViewerScene {
    /// HTML id and folder name of the scene.
    slug: String,
    plot: Option<String>,
    /// relMSE against seconds per image, beside `plot`.
    time_plot: Option<String>,
    /// Squared bias against spp: where the biased methods' error stops falling.
    bias_plot: Option<String>,
    /// The script with the linear values of the scene's images, loaded on first use.
    pixels: Option<String>,
    ratios: Vec<Ratio>,
    colors: BTreeMap<String, String>,
}

/// Writes the viewer for `results` into `out_dir` (created if needed) and returns the path
/// of its index.html. Image paths in `results` are relative to `source_dir` (the study
/// folder holding results.json); each must be a PNG of its scene's size.
pub fn write_report(results: &StudyResults, source_dir: &Path, out_dir: &Path, options: &ReportOptions) -> Result<PathBuf, EvalError> {
    results.validate()?;
    if results.scenes.is_empty() {
        return Err(EvalError::invalid("results", "no scene to report"));
    }
    if out_dir.exists() && !out_dir.is_dir() {
        return Err(EvalError::invalid(out_dir.display().to_string(), "is a file; the report needs a folder"));
    }
    // Two reports into one folder would mix their files, and the roll-back of one that fails
    // would take the other's: the folder is claimed (`.NAME.lock` beside it, in the folder's
    // parent with its links resolved, so that every spelling of it meets the same lock) before
    // it is looked at or made.
    let io = |path: &Path, error| cvtrace_streams::StreamError::Io { path: path.to_path_buf(), error };
    let claimed = match (out_dir.exists(), out_dir.file_name()) {
        (false, Some(name)) => {
            let parent = out_dir.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
            cvtrace_streams::atomic::create_dir_all(parent)?;
            std::fs::canonicalize(parent).map_err(|e| io(parent, e))?.join(name)
        }
        _ => std::fs::canonicalize(out_dir).map_err(|e| io(out_dir, e))?,
    };
    let _claim = OutputLock::acquire(&lock_path_for(&claimed), out_dir)?;
    let index = out_dir.join("index.html");
    if !options.overwrite {
        if index.exists() {
            return Err(cvtrace_streams::StreamError::AlreadyExists { path: index }.into());
        }
        if std::fs::read_dir(out_dir).is_ok_and(|mut d| d.next().is_some()) {
            return Err(EvalError::invalid(
                out_dir.display().to_string(),
                "exists and is not empty; pass --force to write the report into it",
            ));
        }
    }
    let manifest = out_dir.join(MANIFEST);
    if manifest.symlink_metadata().is_ok_and(|m| !m.is_file()) {
        return Err(EvalError::invalid(
            manifest.display().to_string(),
            "is not a regular file; remove it (it is the list of a report's images)",
        ));
    }
    let earlier = earlier_report_files(out_dir);
    let created = !out_dir.exists();
    // Interrupted while filling a folder it made, the report takes the folder away again: the
    // removal is registered before the folder is made, so no interrupt falls between the two.
    let _partial = created.then(|| cvtrace_streams::atomic::remove_folder_on_interrupt(out_dir));
    cvtrace_streams::atomic::create_dir_all(out_dir)?;
    pause_for_tests();
    let written = write_viewer(results, source_dir, out_dir, options, &index, &earlier);
    match written {
        // In a folder this call made, a failed report takes back what it wrote, and the folder
        // if nothing else is in it: never a file it did not write.
        Err(e) if created => {
            remove_own_files(out_dir);
            Err(e)
        }
        Err(e) => Err(e),
        Ok(files) => {
            remove_stale_images(out_dir, &earlier, &files);
            write_text(&out_dir.join(MANIFEST), &manifest_text(&files))?;
            Ok(index)
        }
    }
}

/// Testing aid, not for users: with `CVTRACE_TEST_PAUSE_REPORT=FILE` in the environment, a
/// report that has made (or found) its folder creates FILE and waits, at most a minute, until
/// FILE is removed, so that a test can act at this known point (start a second report, put a
/// file into the folder).
fn pause_for_tests() {
    let Some(signal) = std::env::var_os("CVTRACE_TEST_PAUSE_REPORT") else { return };
    if std::fs::write(&signal, b"paused\n").is_err() {
        return;
    }
    let start = std::time::Instant::now();
    while Path::new(&signal).exists() && start.elapsed() < std::time::Duration::from_secs(60) {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// Removes what a report wrote into `out_dir` (a folder it made): its top-level files, the
/// images and plots its [`MANIFEST`] lists (written before them), then the folders that are
/// left empty, `out_dir` last. Anything else stays.
fn remove_own_files(out_dir: &Path) {
    let listed = earlier_report_files(out_dir);
    for f in REPORT_FILES.iter().copied().filter(|f| *f != MANIFEST).map(String::from).chain(listed.iter().cloned()) {
        let path = out_dir.join(&f);
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
            let _ = std::fs::remove_file(&path);
        }
    }
    let _ = std::fs::remove_file(out_dir.join(MANIFEST));
    // The images' folders (`images/<scene>`), then `images` and `plots`, then the report's.
    let mut folders: BTreeSet<PathBuf> = listed.iter().filter_map(|f| Path::new(f).parent().map(|p| out_dir.join(p))).collect();
    folders.extend(REPORT_FOLDERS.iter().map(|f| out_dir.join(f)));
    let mut folders: Vec<PathBuf> = folders.into_iter().collect();
    folders.sort_by_key(|d| std::cmp::Reverse(d.components().count()));
    for d in folders.iter().map(PathBuf::as_path).chain([out_dir]) {
        if std::fs::symlink_metadata(d).is_ok_and(|m| m.is_dir()) {
            let _ = std::fs::remove_dir(d);
        }
    }
}

/// `path` relative to the folder `base` (with `..` where it lies outside), or `path` as it is
/// when it is relative already or the two share no root.
fn relative_to(path: &Path, base: &Path) -> String {
    let Ok(base) = base.canonicalize() else { return path.display().to_string() };
    if !path.is_absolute() {
        return path.display().to_string();
    }
    let (p, b): (Vec<_>, Vec<_>) = (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common <= 1 {
        return path.display().to_string();
    }
    let mut rel = std::path::PathBuf::new();
    for _ in common..b.len() {
        rel.push("..");
    }
    for c in &p[common..] {
        rel.push(c);
    }
    rel.display().to_string()
}

/// The list of images and plots a report keeps in its folder, so that the next report there
/// removes only files a report wrote, never the user's.
const MANIFEST: &str = ".cvtrace-report";

/// Every file a report writes at the top of its folder, and the folders of its images and
/// plots: what nothing else may be written over (`report --markdown`).
pub const REPORT_FILES: &[&str] = &[
    "index.html",
    "viewer.css",
    "viewer.js",
    "data.js",
    "colorbar.png",
    "colorbar-diff.png",
    "colorbar-flip.png",
    "results.json",
    "results.csv",
    MANIFEST,
];
pub const REPORT_FOLDERS: &[&str] = &["images", "plots"];

fn manifest_text<'a>(files: impl IntoIterator<Item = &'a String>) -> String {
    files.into_iter().map(|f| format!("{f}\n")).collect()
}

/// The images and plots an earlier report in `out_dir` wrote, from its [`MANIFEST`]; only
/// plain relative paths under `images/` and `plots/` are taken.
fn earlier_report_files(out_dir: &Path) -> BTreeSet<String> {
    use std::io::Read;
    // A report lists a few files per method and scene; anything beyond 16 MB is not a manifest.
    let mut text = String::new();
    if let Ok(f) = std::fs::File::open(out_dir.join(MANIFEST)) {
        let _ = f.take(16 << 20).read_to_string(&mut text);
    }
    text.lines()
        .filter(|l| (l.starts_with("images/") || l.starts_with("plots/")) && !l.split('/').any(|c| c.is_empty() || c == "." || c == ".."))
        .map(str::to_string)
        .collect()
}

/// Removes what the earlier report wrote and this one no longer uses (a report redone with
/// --force would otherwise carry old scenes' images), then the folders that became empty.
fn remove_stale_images(out_dir: &Path, earlier: &BTreeSet<String>, keep: &BTreeSet<String>) {
    let Ok(root) = out_dir.canonicalize() else { return };
    for rel in earlier.difference(keep) {
        let path = out_dir.join(rel);
        // Never through a link to somewhere else: the folder holding the file must be inside.
        let inside = path.parent().and_then(|d| d.canonicalize().ok()).is_some_and(|d| d.starts_with(&root));
        if inside && std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_file()) {
            let _ = std::fs::remove_file(&path);
        }
        // Deepest first; only empty ones inside the report go, never the report folder itself.
        for dir in Path::new(rel).ancestors().skip(1).filter(|d| !d.as_os_str().is_empty()) {
            let dir = out_dir.join(dir);
            if std::fs::symlink_metadata(&dir).is_ok_and(|m| m.is_dir()) {
                let _ = std::fs::remove_dir(dir);
            }
        }
    }
}

/// The report's files; returns the images and plots it wrote, relative to `out_dir`. Every
/// source image is checked before anything is written, and the images and plots about to be
/// written are added to the [`MANIFEST`] first: a report that fails or is interrupted half-way
/// leaves only files a manifest lists, which the next report in the folder removes.
fn write_viewer(
    results: &StudyResults,
    source_dir: &Path,
    out_dir: &Path,
    options: &ReportOptions,
    index: &Path,
    earlier: &BTreeSet<String>,
) -> Result<BTreeSet<String>, EvalError> {
    let mut files = BTreeSet::new();
    let mut out = results.clone();
    let mut copies = Vec::new();
    let mut slugs = BTreeSet::new();
    let mut plots = Vec::new();
    for scene in out.scenes.iter_mut() {
        // A page meant to be shared names no local absolute path: the reference is given
        // relative to the study folder.
        scene.reference.path = relative_to(Path::new(&scene.reference.path), source_dir);
        let slug = unique_slug(&scene.name, &mut slugs);
        let mut copier = ImageCopier::new(source_dir, &slug, scene);
        if let Some(p) = scene.reference.image.as_mut() {
            *p = copier.plan(p, &format!("scene `{}`, reference image", scene.name))?;
        }
        let name = scene.name.clone();
        for m in scene.methods.iter_mut() {
            for (field, what) in [
                (&mut m.image, "image"),
                (&mut m.error_map, "error_map"),
                (&mut m.difference_map, "difference_map"),
                (&mut m.flip_map, "flip_map"),
            ] {
                if let Some(p) = field.as_mut() {
                    *p = copier.plan(p, &format!("scene `{name}`, method `{}`, {what}", m.name))?;
                }
            }
        }
        files.extend(copier.copies.iter().map(|(_, dst)| dst.clone()));
        copies.extend(copier.copies);
        let pixels = pixels_script(scene, source_dir, &slug)?.map(|text| (format!("images/{slug}/pixels.js"), text));
        files.extend(pixels.iter().map(|(rel, _)| rel.clone()));
        let plot_rel = format!("plots/{slug}.svg");
        let time_rel = format!("plots/{slug}.time.svg");
        let bias_rel = format!("plots/{slug}.bias.svg");
        files.insert(plot_rel.clone());
        files.insert(time_rel.clone());
        files.insert(bias_rel.clone());
        plots.push((slug, plot_rel, time_rel, bias_rel, pixels));
    }
    write_text(&out_dir.join(MANIFEST), &manifest_text(earlier.union(&files)))?;

    for (src, dst) in &copies {
        let dst = out_dir.join(dst);
        if let Some(dir) = dst.parent() {
            cvtrace_streams::atomic::create_dir_all(dir)?;
        }
        write_atomically(&dst, true, |tmp| std::fs::copy(src, tmp).map(|_| ()))?;
    }
    let mut scenes = Vec::new();
    for (scene, (slug, plot_rel, time_rel, bias_rel, pixels)) in out.scenes.iter_mut().zip(plots) {
        cvtrace_streams::atomic::create_dir_all(&out_dir.join("plots"))?;
        let mut plot_of = |axis, y, rel: String| -> Result<Option<String>, EvalError> {
            let written = write_convergence_svg_of(scene, axis, y, &out_dir.join(&rel), true)?;
            if !written {
                files.remove(&rel);
            }
            Ok(written.then_some(rel))
        };
        let plot = plot_of(XAxis::Spp, YAxis::RelMse, plot_rel)?;
        let time_plot = plot_of(XAxis::Seconds, YAxis::RelMse, time_rel)?;
        let bias_plot = plot_of(XAxis::Spp, YAxis::Bias2, bias_rel)?;
        let pixels = match pixels {
            Some((rel, text)) => {
                cvtrace_streams::atomic::create_dir_all(&out_dir.join("images").join(&slug))?;
                write_text(&out_dir.join(&rel), &text)?;
                Some(rel)
            }
            None => None,
        };
        // The values files stay in the study: the report carries them in pixels.js.
        scene.reference.values = None;
        scene.methods.iter_mut().for_each(|m| m.values = None);
        let colors =
            scene.ordered_methods().iter().enumerate().map(|(i, m)| (m.name.clone(), hex(method_colour(scene, &m.name, i)))).collect();
        scenes.push(ViewerScene { slug, plot, time_plot, bias_plot, pixels, ratios: scene.ratios(), colors });
    }

    write_colorbar_png(&out_dir.join("colorbar.png"), 256, 12, true)?;
    write_difference_colorbar_png(&out_dir.join("colorbar-diff.png"), 256, 12, true)?;
    write_flip_colorbar_png(&out_dir.join("colorbar-flip.png"), 256, 12, true)?;
    out.write_json(&out_dir.join("results.json"), true)?;
    write_csv(&out, &out_dir.join("results.csv"), true)?;
    let data = ViewerData {
        title: &options.title,
        results: &out,
        scenes,
        geomean_ratios: out.geomean_ratios(),
        colorbar: "colorbar.png",
        difference_colorbar: "colorbar-diff.png",
        flip_colorbar: "colorbar-flip.png",
        files: BTreeMap::from([("results.json", "results.json"), ("results.csv", "results.csv")]),
    };
    let json = serde_json::to_string(&data).map_err(|e| EvalError::invalid("report data", e.to_string()))?;
    write_text(&out_dir.join("data.js"), &format!("window.CVTRACE_DATA = {json};\n"))?;
    write_text(&out_dir.join("viewer.css"), VIEWER_CSS)?;
    write_text(&out_dir.join("viewer.js"), VIEWER_JS)?;
    let title = html_escape(&options.title);
    write_text(
        index,
        &INDEX_HTML.replace("<title>cvtrace — estimator comparison</title>", &format!("<title>{title} — estimator comparison</title>")),
    )?;
    Ok(files)
}

/// The script that hands the viewer the linear values of a scene's images (the reference's and
/// every method's that has a values file), or `None` when the study recorded none. Each file
/// is read and checked against the scene's size here, before the report writes anything.
fn pixels_script(scene: &SceneResult, source_dir: &Path, slug: &str) -> Result<Option<String>, EvalError> {
    let read = |rel: &str, ctx: String| -> Result<serde_json::Value, EvalError> {
        let path = source_dir.join(rel);
        let v = read_values_exr(&path).map_err(|e| EvalError::invalid(&ctx, e.to_string()))?;
        if (v.width, v.height) != (scene.width, scene.height) {
            return Err(EvalError::invalid(
                ctx,
                format!("{} is {}x{}, expected the scene size {}x{}", path.display(), v.width, v.height, scene.width, scene.height),
            ));
        }
        Ok(v.to_json())
    };
    let mut methods = serde_json::Map::new();
    for m in &scene.methods {
        if let Some(rel) = &m.values {
            methods.insert(m.name.clone(), read(rel, format!("scene `{}`, method `{}`, values", scene.name, m.name))?);
        }
    }
    let reference = match &scene.reference.values {
        Some(rel) => Some(read(rel, format!("scene `{}`, reference values", scene.name))?),
        None => None,
    };
    if methods.is_empty() && reference.is_none() {
        return Ok(None);
    }
    let data = serde_json::json!({ "width": scene.width, "height": scene.height, "reference": reference, "methods": methods });
    let key = serde_json::to_string(slug).map_err(|e| EvalError::invalid("report data", e.to_string()))?;
    Ok(Some(format!("(window.CVTRACE_PIXELS = window.CVTRACE_PIXELS || {{}})[{key}] = {data};\n")))
}

fn write_text(path: &Path, text: &str) -> Result<(), EvalError> {
    write_atomically(path, true, |tmp| std::fs::write(tmp, text.as_bytes()))?;
    Ok(())
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// A file- and id-safe name for a scene, unique within the report.
pub fn slug(name: &str) -> String {
    let mut s = String::new();
    for ch in name.chars() {
        if ch.is_ascii_alphanumeric() {
            s.push(ch.to_ascii_lowercase());
        } else if !s.ends_with('-') {
            s.push('-');
        }
    }
    let s = s.trim_matches('-').to_string();
    if s.is_empty() {
        "scene".into()
    } else {
        s
    }
}

fn unique_slug(name: &str, taken: &mut BTreeSet<String>) -> String {
    let base = slug(name);
    let mut s = base.clone();
    let mut k = 2;
    while !taken.insert(s.clone()) {
        s = format!("{base}-{k}");
        k += 1;
    }
    s
}

/// Plans the copies of one scene's images into `images/<slug>/`, checking each is a PNG of the
/// scene's size.
struct ImageCopier<'a> {
    source_dir: &'a Path,
    folder: String,
    width: usize,
    height: usize,
    done: HashMap<String, String>,
    names: BTreeSet<String>,
    /// Source file and the copy's path relative to the report folder.
    copies: Vec<(PathBuf, String)>,
}

impl<'a> ImageCopier<'a> {
    fn new(source_dir: &'a Path, slug: &str, scene: &SceneResult) -> Self {
        ImageCopier {
            source_dir,
            folder: format!("images/{slug}"),
            width: scene.width,
            height: scene.height,
            done: HashMap::new(),
            names: BTreeSet::new(),
            copies: Vec::new(),
        }
    }

    /// Returns the copy's path relative to the report folder.
    fn plan(&mut self, rel: &str, ctx: &str) -> Result<String, EvalError> {
        if let Some(d) = self.done.get(rel) {
            return Ok(d.clone());
        }
        let src = self.source_dir.join(rel);
        let (w, h) = png_size(&src).map_err(|m| EvalError::invalid(ctx, format!("{}: {m}", src.display())))?;
        if (w, h) != (self.width, self.height) {
            return Err(EvalError::invalid(
                ctx,
                format!("{} is {w}x{h}, expected the scene size {}x{}", src.display(), self.width, self.height),
            ));
        }
        // The copy's name goes into the page as a link, so it keeps to characters that need no
        // URL encoding (a results file from another tool may name `pt #1?.png`).
        let file: String = Path::new(rel)
            .file_name()
            .map(|f| f.to_string_lossy().chars().map(|c| if c.is_ascii_alphanumeric() || "._-".contains(c) { c } else { '-' }).collect())
            .unwrap_or_else(|| "image.png".into());
        let mut name = file.clone();
        let mut k = 2;
        while !self.names.insert(name.clone()) {
            name = format!("{k}-{file}");
            k += 1;
        }
        let dst = format!("{}/{name}", self.folder);
        self.copies.push((src, dst.clone()));
        self.done.insert(rel.to_string(), dst.clone());
        Ok(dst)
    }
}

/// Width and height from a PNG's IHDR chunk, or why the file is not a PNG.
pub fn png_size(path: &Path) -> Result<(usize, usize), String> {
    use std::io::Read;
    cvtrace_streams::input_file::regular_file(path).map_err(|e| e.to_string())?;
    let mut f = std::fs::File::open(path).map_err(|e| format!("cannot open: {e}"))?;
    let mut head = [0u8; 24];
    f.read_exact(&mut head).map_err(|_| "too short to be a PNG".to_string())?;
    if head[..8] != [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a] || &head[12..16] != b"IHDR" {
        return Err("not a PNG file".into());
    }
    let w = u32::from_be_bytes([head[16], head[17], head[18], head[19]]) as usize;
    let h = u32::from_be_bytes([head[20], head[21], head[22], head[23]]) as usize;
    Ok((w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_paths_are_shown_relative_to_the_study() {
        let dir = tempfile::tempdir().unwrap();
        let study = dir.path().join("studies/cbox");
        std::fs::create_dir_all(&study).unwrap();
        let root = dir.path().canonicalize().unwrap();
        assert_eq!(relative_to(&root.join("studies/cbox/ref.exr"), &study), "ref.exr");
        assert_eq!(relative_to(&root.join("scenes/cbox/scene.ref.exr"), &study), "../../scenes/cbox/scene.ref.exr");
        assert_eq!(relative_to(Path::new("already/relative.exr"), &study), "already/relative.exr");
    }
    use crate::synthetic::{write_synthetic_study, SyntheticOptions};

    fn study() -> (tempfile::TempDir, StudyResults) {
        let dir = tempfile::tempdir().unwrap();
        let results = write_synthetic_study(&dir.path().join("study"), &SyntheticOptions::small()).unwrap();
        (dir, results)
    }

    #[test]
    fn report_folder_is_self_contained() {
        let (dir, mut results) = study();
        // A results file from another tool may name its images anything: the page's links to
        // the copies must still resolve without URL encoding.
        let odd = "pt #1 %41?.png";
        let m = &mut results.scenes[0].methods[0];
        std::fs::rename(dir.path().join("study").join(m.image.as_ref().unwrap()), dir.path().join("study").join(odd)).unwrap();
        m.image = Some(odd.into());
        let out = dir.path().join("report");
        let index = write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap();
        assert_eq!(index, out.join("index.html"));
        for f in REPORT_FILES {
            assert!(out.join(f).is_file(), "{f} missing");
        }
        // And nothing else: REPORT_FILES and REPORT_FOLDERS are the whole list.
        for e in std::fs::read_dir(&out).unwrap() {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            assert!(REPORT_FILES.contains(&name.as_str()) || REPORT_FOLDERS.contains(&name.as_str()), "{name} is not listed");
        }
        let data = std::fs::read_to_string(out.join("data.js")).unwrap();
        let json = data.trim().strip_prefix("window.CVTRACE_DATA = ").unwrap().strip_suffix(';').unwrap();
        let v: serde_json::Value = serde_json::from_str(json).unwrap();
        // Every image the page references exists inside the report folder.
        let mut refs = Vec::new();
        for s in v["results"]["scenes"].as_array().unwrap() {
            refs.extend(s["reference"]["image"].as_str().map(String::from));
            for m in s["methods"].as_array().unwrap() {
                refs.extend(m["image"].as_str().map(String::from));
                refs.extend(m["error_map"].as_str().map(String::from));
                refs.extend(m["flip_map"].as_str().map(String::from));
            }
        }
        for s in v["scenes"].as_array().unwrap() {
            refs.extend(s["plot"].as_str().map(String::from));
        }
        assert!(refs.len() >= 10, "{refs:?}");
        for r in &refs {
            assert!(!r.starts_with('/') && !r.contains(".."), "{r}");
            assert!(r.chars().all(|c| c.is_ascii_alphanumeric() || "._-/".contains(c)), "{r} needs URL encoding");
            assert!(out.join(r).is_file(), "{r} not copied");
        }
        // The copied results are valid and point at the copies.
        let copied = StudyResults::read_json(&out.join("results.json")).unwrap();
        assert_eq!(copied.scenes[0].methods.len(), results.scenes[0].methods.len());
        let html = std::fs::read_to_string(&index).unwrap();
        assert!(!html.contains("http://") && !html.contains("https://"), "must work offline");
        // A second run without overwrite is refused; with it, it succeeds.
        let again = write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default());
        assert!(again.unwrap_err().to_string().contains("already exists"));
        let opts = ReportOptions { overwrite: true, ..Default::default() };
        write_report(&results, &dir.path().join("study"), &out, &opts).unwrap();
    }

    #[test]
    fn a_folder_claimed_by_another_report_is_left_alone() {
        let (dir, results) = study();
        let out = dir.path().join("report");
        // Another process's claim, with the folder spelt through a link to its parent.
        std::os::unix::fs::symlink(dir.path(), dir.path().join("here")).unwrap();
        let claim = OutputLock::acquire(&lock_path_for(&dir.path().canonicalize().unwrap().join("report")), &out).unwrap();
        for overwrite in [false, true] {
            let e = write_report(
                &results,
                &dir.path().join("study"),
                &dir.path().join("here/report"),
                &ReportOptions { overwrite, ..Default::default() },
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains("another cvtrace process"), "{e}");
            assert!(!out.exists(), "the folder was made while another report holds it");
        }
        drop(claim);
        write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap();
        assert!(!dir.path().join(".report.lock").exists(), "the claim goes with the call");
    }

    fn unbase64(text: &str) -> Vec<u8> {
        let value = |c: u8| "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/".bytes().position(|a| a == c).unwrap() as u32;
        let mut out = Vec::new();
        for chunk in text.as_bytes().chunks(4) {
            let pad = chunk.iter().filter(|&&c| c == b'=').count();
            let n = chunk.iter().filter(|&&c| c != b'=').fold(0u32, |n, &c| n << 6 | value(c)) << (6 * pad);
            out.extend_from_slice(&n.to_be_bytes()[1..4 - pad]);
        }
        out
    }

    #[test]
    fn pixels_script_carries_every_values_file_exactly() {
        let (dir, results) = study();
        let out = dir.path().join("report");
        write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap();
        let scene = &results.scenes[0];
        let slug = slug(&scene.name);
        let rel = format!("images/{slug}/pixels.js");
        let text = std::fs::read_to_string(out.join(&rel)).unwrap();
        assert!(std::fs::read_to_string(out.join(MANIFEST)).unwrap().lines().any(|l| l == rel), "listed in the manifest");
        let prefix = format!("(window.CVTRACE_PIXELS = window.CVTRACE_PIXELS || {{}})[\"{slug}\"] = ");
        let json: serde_json::Value =
            serde_json::from_str(text.strip_prefix(&prefix).unwrap().trim_end().strip_suffix(';').unwrap()).unwrap();
        assert_eq!((json["width"].as_u64(), json["height"].as_u64()), (Some(scene.width as u64), Some(scene.height as u64)));
        let floats = |b64: &serde_json::Value| -> Vec<f32> {
            unbase64(b64.as_str().unwrap()).chunks(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
        };
        for m in &scene.methods {
            let v = crate::pixels::read_values_exr(&dir.path().join("study").join(m.values.as_ref().unwrap())).unwrap();
            let rgb = floats(&json["methods"][&m.name]["rgb"]);
            assert_eq!(rgb.len(), 3 * scene.width * scene.height, "{}", m.name);
            for (i, px) in rgb.chunks(3).enumerate() {
                assert_eq!(px, [v.rgb[0][i], v.rgb[1][i], v.rgb[2][i]], "{} pixel {i}", m.name);
            }
            assert_eq!(floats(&json["methods"][&m.name]["relmse"]), v.relmse.unwrap(), "{}", m.name);
            assert_eq!(floats(&json["methods"][&m.name]["flip"]), v.flip.unwrap(), "{}", m.name);
        }
        let reference = floats(&json["reference"]["rgb"]);
        assert_eq!(reference.len(), 3 * scene.width * scene.height);
        assert!(json["reference"].get("relmse").is_none());
        // The report's copy of the results names no values file it did not copy.
        let copied = StudyResults::read_json(&out.join("results.json")).unwrap();
        assert!(copied.scenes[0].reference.values.is_none() && copied.scenes[0].methods.iter().all(|m| m.values.is_none()));
        // A values file of another size is refused, naming the method.
        let ours = scene.method("ours").unwrap().values.clone().unwrap();
        crate::pixels::write_values_exr(&dir.path().join("study").join(&ours), &cvtrace_streams::Image::new(3, 2), None, None, true)
            .unwrap();
        let e =
            write_report(&results, &dir.path().join("study"), &dir.path().join("r2"), &ReportOptions::default()).unwrap_err().to_string();
        assert!(e.contains("`ours`") && e.contains("3x2"), "{e}");
    }

    #[test]
    fn results_of_older_studies_still_read_and_report() {
        let (dir, results) = study();
        // What a study wrote before values, difference maps, FLIP and times per point were recorded.
        let mut json: serde_json::Value = serde_json::from_str(&results.to_json()).unwrap();
        let scene = &mut json["scenes"][0];
        scene.as_object_mut().unwrap().remove("difference_scale");
        scene.as_object_mut().unwrap().remove("flip");
        scene["reference"].as_object_mut().unwrap().remove("values");
        for m in scene["methods"].as_array_mut().unwrap() {
            for field in ["values", "difference_map", "flip_mean", "flip_se", "flip_per_seed", "flip_map"] {
                m.as_object_mut().unwrap().remove(field);
            }
        }
        for p in scene["convergence"].as_array_mut().unwrap() {
            p.as_object_mut().unwrap().remove("seconds");
        }
        let path = dir.path().join("study/old.json");
        std::fs::write(&path, serde_json::to_string(&json).unwrap()).unwrap();
        let old = StudyResults::read_json(&path).unwrap();
        assert!(old.scenes[0].convergence.iter().all(|p| p.seconds.is_none()));
        assert!(old.scenes[0].flip.is_none() && old.scenes[0].methods.iter().all(|m| m.flip_mean.is_none() && m.flip_map.is_none()));
        assert!(!crate::table::terminal_table(&old.scenes[0]).contains("FLIP"));
        let out = dir.path().join("report");
        write_report(&old, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap();
        let slug = slug(&old.scenes[0].name);
        assert!(out.join(format!("plots/{slug}.svg")).is_file());
        assert!(!out.join(format!("plots/{slug}.time.svg")).exists() && !out.join(format!("images/{slug}/pixels.js")).exists());
    }

    #[test]
    fn missing_or_wrong_images_name_the_file_and_method() {
        let (dir, results) = study();
        let src = dir.path().join("study");
        let ours = results.scenes[0].method("ours").unwrap().image.clone().unwrap();
        std::fs::remove_file(src.join(&ours)).unwrap();
        let err = write_report(&results, &src, &dir.path().join("r1"), &ReportOptions::default()).unwrap_err().to_string();
        assert!(err.contains("`ours`") && err.contains(&ours), "{err}");
        // A PNG of another size.
        cvtrace_streams::preview::write_png(&src.join(&ours), &cvtrace_streams::Image::new(3, 2), 0.0, true).unwrap();
        let err = write_report(&results, &src, &dir.path().join("r2"), &ReportOptions::default()).unwrap_err().to_string();
        assert!(err.contains("3x2") && err.contains("expected the scene size"), "{err}");
        // Not a PNG at all.
        std::fs::write(src.join(&ours), b"GIF89a........................").unwrap();
        let err = write_report(&results, &src, &dir.path().join("r3"), &ReportOptions::default()).unwrap_err().to_string();
        assert!(err.contains("not a PNG"), "{err}");
        // Each failure left no report folder behind.
        for r in ["r1", "r2", "r3"] {
            assert!(!dir.path().join(r).exists(), "{r} left behind");
        }
    }

    #[test]
    fn a_redone_report_drops_what_it_no_longer_shows() {
        let (dir, results) = study();
        let out = dir.path().join("report");
        write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap();
        // What an earlier report of another scene would have left, and listed as its own.
        std::fs::create_dir_all(out.join("images/old-scene")).unwrap();
        std::fs::write(out.join("images/old-scene/ours.png"), b"old").unwrap();
        std::fs::write(out.join("plots/old-scene.svg"), b"old").unwrap();
        let mut manifest = std::fs::read_to_string(out.join(MANIFEST)).unwrap();
        assert!(manifest.lines().count() >= 4, "{manifest}");
        manifest += "images/old-scene/ours.png\nplots/old-scene.svg\nimages/../../escape.png\n";
        std::fs::write(out.join(MANIFEST), manifest).unwrap();
        // The user's own files, in the report's folders too.
        std::fs::write(out.join("notes.txt"), b"the user's").unwrap();
        std::fs::create_dir_all(out.join("images/photos")).unwrap();
        std::fs::write(out.join("images/photos/me.jpg"), b"the user's").unwrap();
        std::fs::write(out.join("plots/mine.svg"), b"the user's").unwrap();
        std::fs::write(dir.path().join("escape.png"), b"the user's").unwrap();
        // A folder under images/ that links elsewhere: the manifest's entry through it is not removed.
        std::fs::create_dir_all(dir.path().join("elsewhere")).unwrap();
        std::fs::write(dir.path().join("elsewhere/x.png"), b"the user's").unwrap();
        std::os::unix::fs::symlink(dir.path().join("elsewhere"), out.join("images/linked")).unwrap();
        std::fs::write(out.join(MANIFEST), std::fs::read_to_string(out.join(MANIFEST)).unwrap() + "images/linked/x.png\n").unwrap();
        // Without --force a folder with files in it is refused, with or without an index.html.
        let e = write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap_err().to_string();
        assert!(e.contains("index.html") && e.contains("already exists"), "{e}");
        std::fs::remove_file(out.join("index.html")).unwrap();
        let e = write_report(&results, &dir.path().join("study"), &out, &ReportOptions::default()).unwrap_err().to_string();
        assert!(e.contains("not empty") && e.contains("--force"), "{e}");
        let opts = ReportOptions { overwrite: true, ..Default::default() };
        write_report(&results, &dir.path().join("study"), &out, &opts).unwrap();
        assert!(!out.join("images/old-scene").exists() && !out.join("plots/old-scene.svg").exists());
        for f in ["notes.txt", "images/photos/me.jpg", "plots/mine.svg", "../escape.png"] {
            assert!(out.join(f).is_file(), "{f}: the user's file was removed");
        }
        assert!(!std::fs::read_to_string(out.join(MANIFEST)).unwrap().contains("old-scene"));
        assert!(dir.path().join("elsewhere/x.png").is_file(), "a file outside the report was removed through a link");
        let slug = slug(&results.scenes[0].name);
        assert!(std::fs::read_dir(out.join("images").join(&slug)).unwrap().count() >= 4, "this report's images stay");
    }

    /// Files under `dir`, relative to it.
    fn files_under(dir: &Path) -> BTreeSet<String> {
        let mut out = BTreeSet::new();
        let mut stack = vec![dir.to_path_buf()];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).unwrap() {
                let p = e.unwrap().path();
                if p.is_dir() {
                    stack.push(p);
                } else {
                    out.insert(p.strip_prefix(dir).unwrap().to_string_lossy().into_owned());
                }
            }
        }
        out
    }

    #[test]
    fn a_report_that_fails_half_way_leaves_only_listed_images() {
        let (dir, mut results) = study();
        let src = dir.path().join("study");
        let out = dir.path().join("report");
        // The user's folder, with a file where the report's plots folder would go: the report
        // fails after copying its images.
        std::fs::create_dir_all(&out).unwrap();
        std::fs::write(out.join("plots"), b"the user's").unwrap();
        let opts = ReportOptions { overwrite: true, ..Default::default() };
        let e = write_report(&results, &src, &out, &opts).unwrap_err().to_string();
        assert!(e.contains("plots"), "{e}");
        let left = files_under(&out.join("images"));
        assert!(left.len() >= 4, "the failure should come after the images: {left:?}");
        let listed = earlier_report_files(&out);
        for f in &left {
            assert!(listed.contains(&format!("images/{f}")), "images/{f} was left behind unlisted");
        }
        // The next report, without one of the methods, cleans up what the failed one left.
        std::fs::remove_file(out.join("plots")).unwrap();
        let dropped = results.scenes[0].methods.pop().unwrap();
        write_report(&results, &src, &out, &opts).unwrap();
        let copy =
            listed.iter().find(|f| f.ends_with(Path::new(dropped.image.as_ref().unwrap()).file_name().unwrap().to_str().unwrap())).unwrap();
        assert!(!out.join(copy).exists(), "{copy}: the failed report's image stayed");
        assert!(out.join("plots").is_dir());
    }

    #[test]
    fn slugs_are_safe_and_unique() {
        assert_eq!(slug("Cornell Box (96 spp)"), "cornell-box-96-spp");
        assert_eq!(slug("../.."), "scene");
        let mut taken = BTreeSet::new();
        assert_eq!(unique_slug("a b", &mut taken), "a-b");
        assert_eq!(unique_slug("a/b", &mut taken), "a-b-2");
    }
}
