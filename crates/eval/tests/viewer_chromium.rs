//! The viewer in a real browser: build a report from a synthetic two-scene study, open its
//! index.html from file:// in headless Chromium (no server), take a screenshot and dump the
//! DOM after the scripts ran, then check that every image loaded and that the tables hold
//! the numbers of the results JSON.
//!
//! Skipped, with a message, only when /usr/bin/chromium is absent (the setup script installs
//! it for CI: `apt-get install chromium`).
use cvtrace_eval::report::slug;
use cvtrace_eval::synthetic::{write_synthetic_study, SyntheticOptions};
use cvtrace_eval::{write_report, ReportOptions, StudyResults};
use std::io::Read;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const CHROMIUM: &str = "/usr/bin/chromium";

/// Whether the browser is installed. `make test` sets `CVTRACE_REQUIRE_TOOLS` (its setup installs
/// chromium), so there a missing browser fails the test instead of skipping it.
fn have_chromium() -> bool {
    let found = Path::new(CHROMIUM).exists();
    assert!(found || std::env::var_os("CVTRACE_REQUIRE_TOOLS").is_none(), "{CHROMIUM} is not installed and CVTRACE_REQUIRE_TOOLS is set");
    found
}
const WINDOW: (u32, u32) = (1400, 1000);

/// Two synthetic scenes in one study folder (`a/…`, `b/…`), so ids, slugs and the
/// geometric-mean block are exercised too.
fn two_scene_study(dir: &Path) -> StudyResults {
    let mut scenes = Vec::new();
    for (sub, name, w, h) in [("a", "synthetic box", 96, 72), ("b", "Wide box (2:1)", 80, 40)] {
        let opts = SyntheticOptions { scene_name: name.into(), width: w, height: h, ..SyntheticOptions::small() };
        let r = write_synthetic_study(&dir.join(sub), &opts).unwrap();
        let mut scene = r.scenes.into_iter().next().unwrap();
        let prefix = |p: &mut Option<String>| {
            if let Some(s) = p.as_mut() {
                *s = format!("{sub}/{s}");
            }
        };
        prefix(&mut scene.reference.image);
        prefix(&mut scene.reference.values);
        for m in scene.methods.iter_mut() {
            prefix(&mut m.image);
            prefix(&mut m.error_map);
            prefix(&mut m.difference_map);
            prefix(&mut m.flip_map);
            prefix(&mut m.values);
        }
        scenes.push(scene);
    }
    let results = StudyResults::new(scenes);
    results.write_json(&dir.join("results.json"), true).unwrap();
    // Round-trip through the file, as `cvtrace report` does.
    StudyResults::read_json(&dir.join("results.json")).unwrap()
}

fn file_url(p: &Path) -> String {
    let mut s = String::from("file://");
    for b in p.to_str().expect("temp paths are UTF-8").bytes() {
        match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'/' | b'-' | b'_' | b'.' | b'~' => s.push(b as char),
            _ => s.push_str(&format!("%{b:02X}")),
        }
    }
    s
}

/// Runs Chromium with the flags that keep it offline and quiet; kills its whole process
/// group (and only it) on timeout. Returns stdout; fails on any uncaught script error
/// (console messages go to stderr with --enable-logging).
fn chromium(profile: &Path, extra: &[String], url: &str) -> String {
    let mut cmd = Command::new(CHROMIUM);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--no-default-browser-check",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-extensions",
        "--disable-default-apps",
        "--disable-dev-shm-usage",
        "--metrics-recording-only",
        "--mute-audio",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
        "--virtual-time-budget=5000",
        "--enable-logging=stderr",
        "--v=0",
    ])
    .arg(format!("--user-data-dir={}", profile.display()))
    .arg(format!("--window-size={},{}", WINDOW.0, WINDOW.1))
    .args(extra)
    .arg(url)
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped())
    .process_group(0);
    let mut child = cmd.spawn().expect("start chromium");
    let pid = child.id();
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out_thread = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let err_thread = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break Some(st);
        }
        if start.elapsed() > Duration::from_secs(90) {
            // Our own process group only (chromium spawns helpers into it).
            let _ = Command::new("kill").args(["-KILL", "--", &format!("-{pid}")]).status();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let out = out_thread.join().unwrap();
    let err = err_thread.join().unwrap();
    let script_errors: Vec<&str> = err.lines().filter(|l| l.contains("Uncaught") || l.contains("viewer.js")).collect();
    assert!(script_errors.is_empty(), "script errors in the viewer:\n{}", script_errors.join("\n"));
    match status {
        Some(st) if st.success() => out,
        Some(st) => panic!("chromium failed ({st}); stderr:\n{err}"),
        None => panic!("chromium did not finish within 90 s; stderr:\n{err}"),
    }
}

/// Text content right after the start tag carrying `data-key="key"`.
fn cell(dom: &str, key: &str) -> Option<String> {
    let at = dom.find(&format!("data-key=\"{key}\""))?;
    let start = at + dom[at..].find('>')? + 1;
    let end = start + dom[start..].find('<')?;
    Some(dom[start..end].trim().to_string())
}

fn attr(dom: &str, tag_start: &str, name: &str) -> Option<String> {
    let at = dom.find(tag_start)?;
    let tag_end = at + dom[at..].find('>')?;
    let tag = &dom[at..tag_end];
    let k = tag.find(&format!("{name}=\""))? + name.len() + 2;
    Some(tag[k..k + tag[k..].find('"')?].to_string())
}

/// The displayed text must be `value` to four significant digits, or "–" for none.
fn assert_shows(dom: &str, key: &str, value: Option<f64>) {
    let text = cell(dom, key).unwrap_or_else(|| panic!("no cell {key} in the DOM"));
    match value {
        None => assert_eq!(text, "–", "{key}"),
        Some(v) => {
            let shown: f64 = text.parse().unwrap_or_else(|_| panic!("{key}: `{text}` is not a number"));
            assert!((shown - v).abs() <= 5e-4 * v.abs() + 1e-300, "{key}: shows {text}, JSON has {v}");
        }
    }
}

fn decode_png(p: &Path) -> (u32, u32, Vec<u8>, png::ColorType) {
    let dec = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(p).unwrap()));
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf, info.color_type)
}

#[test]
fn viewer_loads_every_image_and_shows_the_json_numbers() {
    if !have_chromium() {
        eprintln!("SKIPPED viewer_chromium: {CHROMIUM} not found. Install it (`apt-get install -y --no-install-recommends chromium`; the project's setup script does this for CI) to run the browser test.");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let study = dir.path().join("study");
    let results = two_scene_study(&study);
    let out = dir.path().join("report");
    let index = write_report(&results, &study, &out, &ReportOptions { title: "viewer test".into(), overwrite: false }).unwrap();
    let url = file_url(&index);

    // 1. Screenshot: exists, has the window size, and is not blank.
    let shot: PathBuf = std::env::var_os("CVTRACE_VIEWER_SCREENSHOT").map(PathBuf::from).unwrap_or_else(|| dir.path().join("shot.png"));
    chromium(&dir.path().join("profile-1"), &[format!("--screenshot={}", shot.display())], &url);
    assert!(shot.is_file(), "no screenshot written");
    let (w, h, px, color) = decode_png(&shot);
    assert_eq!((w, h), WINDOW);
    let channels = match color {
        png::ColorType::Rgba => 4,
        png::ColorType::Rgb => 3,
        other => panic!("unexpected screenshot colour type {other:?}"),
    };
    let colours: std::collections::HashSet<[u8; 3]> = px.chunks(channels).map(|p| [p[0], p[1], p[2]]).collect();
    assert!(colours.len() > 500, "screenshot looks blank: only {} distinct colours", colours.len());
    // The page margin (left 10 px, below the header) is the dark neutral background.
    let at = |x: u32, y: u32| {
        let i = ((y * w + x) as usize) * channels;
        [px[i], px[i + 1], px[i + 2]]
    };
    for y in (60..h).step_by(10) {
        for x in 0..10 {
            let c = at(x, y);
            let (mx, mn) = (*c.iter().max().unwrap(), *c.iter().min().unwrap());
            assert!(mx < 48 && mx - mn < 12, "background at ({x}, {y}) is {c:?}, expected a dark neutral grey");
        }
    }

    // 2. DOM after scripts: every <img> loaded, tables hold the JSON numbers.
    let dom = chromium(&dir.path().join("profile-2"), &["--dump-dom".to_string()], &url);
    assert!(dom.contains("<body"), "no DOM dumped");
    let loaded = attr(&dom, "<body", "data-loaded").expect("body has no data-loaded: did viewer.js run?");
    let (ok, total) = loaded.split_once('/').map(|(a, b)| (a.parse::<usize>().unwrap(), b.parse::<usize>().unwrap())).unwrap();
    let failed_src = attr(&dom, "<body", "data-failed-src").unwrap_or_default();
    assert_eq!(ok, total, "only {ok} of {total} images loaded; failed: {failed_src}");
    assert_eq!(attr(&dom, "<body", "data-ready").as_deref(), Some("1"));
    // Expected images: per scene the previews, the reference, the relMSE, FLIP and difference
    // maps, the ablation previews and the plots (relMSE against spp and time, and bias² against
    // spp where some estimate is positive); plus a colour bar per legend.
    let expected: usize = results
        .scenes
        .iter()
        .map(|s| {
            let photos = s.methods.iter().filter(|m| m.image.is_some()).count();
            let maps = s.methods.iter().filter(|m| !m.ablation && m.error_map.is_some()).count();
            let diffs = s.methods.iter().filter(|m| !m.ablation && m.difference_map.is_some()).count();
            let flips = s.methods.iter().filter(|m| !m.ablation && m.flip_map.is_some()).count();
            assert!(flips > 0, "the synthetic study makes FLIP maps");
            let bias = usize::from(s.convergence.iter().any(|p| p.bias2.is_some_and(|b| b > 0.0)));
            photos + maps + diffs + flips + usize::from(s.reference.image.is_some()) + 2 * usize::from(!s.convergence.is_empty()) + bias + 3
        })
        .sum();
    assert_eq!(total, expected, "number of <img> elements");
    assert_eq!(dom.matches("<img").count(), expected);

    for scene in &results.scenes {
        let sl = slug(&scene.name);
        assert!(dom.contains(&format!("id=\"{sl}\"")), "scene section {sl} missing");
        for m in &scene.methods {
            let k = |f: &str| format!("{sl}/{}/{f}", m.name);
            assert_shows(&dom, &k("relmse_mean"), Some(m.relmse_mean));
            assert_shows(&dom, &k("relmse_se"), m.relmse_se);
            assert_shows(&dom, &k("bias2"), m.bias2);
            assert_shows(&dom, &k("variance"), m.variance);
            assert_shows(&dom, &k("mse_mean"), Some(m.mse_mean));
            assert_shows(&dom, &k("flip_mean"), m.flip_mean);
            assert_shows(&dom, &k("flip_se"), m.flip_se);
            let t = cell(&dom, &k("time_total")).unwrap();
            let shown: f64 = t.parse().unwrap();
            assert!((shown - m.time_seconds.total()).abs() <= 5e-4 + 5e-3 * m.time_seconds.total(), "{} time {t}", m.name);
            let pt2n = scene.method("pt2n").unwrap().relmse_mean;
            assert_shows(&dom, &k("over_pt2n"), Some(m.relmse_mean / pt2n));
        }
        let ratios = scene.ratios();
        assert_eq!(ratios.len(), 3, "ours/IDUW, ours/CV, ours/PT(2n)");
        for r in &ratios {
            let key = format!("{sl}/ratio/{}/{}", r.numerator, r.denominator);
            assert_shows(&dom, &key, Some(r.value));
            assert_shows(&dom, &format!("{key}/se"), r.se);
        }
        let noise = scene.reference.noise.unwrap().relmse;
        assert_shows(&dom, &format!("{sl}/reference/noise"), Some(noise));
        let scale = scene.error_map_scale.as_ref().unwrap();
        assert_shows(&dom, &format!("{sl}/error_map/min"), Some(10f64.powf(scale.log10_min)));
    }
    for r in results.geomean_ratios() {
        let key = format!("geomean/{}/{}", r.numerator, r.denominator);
        assert_shows(&dom, &key, Some(r.value));
        assert_shows(&dom, &format!("{key}/se"), r.se);
    }
}

#[test]
fn viewer_copes_with_minimal_results() {
    if !have_chromium() {
        eprintln!("SKIPPED viewer_chromium: {CHROMIUM} not found.");
        return;
    }
    // What `cvtrace compare` produces: one seed, no images, no maps, no plot, unknown spp.
    let dir = tempfile::tempdir().unwrap();
    let study = dir.path().join("study");
    let full = write_synthetic_study(&study, &SyntheticOptions { convergence_spp: vec![], ..SyntheticOptions::small() }).unwrap();
    let mut scene = full.scenes[0].clone();
    scene.spp_per_stream = 0;
    scene.seeds = 1;
    scene.reference.image = None;
    scene.reference.noise = None;
    scene.reference.values = None;
    scene.error_map_scale = None;
    scene.difference_scale = None;
    scene.methods.retain(|m| m.name == "pt" || m.name == "ours");
    for m in scene.methods.iter_mut() {
        m.image = None;
        m.error_map = None;
        m.difference_map = None;
        m.flip_map = None;
        m.flip_se = None;
        m.values = None;
        m.relmse_se = None;
        m.bias2 = None;
        m.variance = None;
        m.spp_total = 0;
    }
    let results = StudyResults::new(vec![scene]);
    let out = dir.path().join("report");
    let index = write_report(&results, &study, &out, &ReportOptions::default()).unwrap();
    let dom = chromium(&dir.path().join("profile"), &["--dump-dom".to_string()], &file_url(&index));
    assert_eq!(attr(&dom, "<body", "data-loaded").as_deref(), Some("0/0"));
    assert_eq!(attr(&dom, "<body", "data-ready").as_deref(), Some("1"), "viewer.js did not finish");
    let sl = slug(&results.scenes[0].name);
    for m in &results.scenes[0].methods {
        assert_shows(&dom, &format!("{sl}/{}/relmse_mean", m.name), Some(m.relmse_mean));
        assert_shows(&dom, &format!("{sl}/{}/bias2", m.name), None);
        // `cvtrace compare` has a FLIP mean of one seed, without a map.
        assert_shows(&dom, &format!("{sl}/{}/flip_mean", m.name), m.flip_mean);
        assert_shows(&dom, &format!("{sl}/{}/flip_se", m.name), None);
    }
    assert!(!dom.contains("grid flips"), "no FLIP view without FLIP maps");
    assert!(dom.contains("No convergence data"));

    // Results of a study by an older cvtrace: images and a convergence plot, but no linear
    // values, no difference maps and no times per point.
    let mut old = full.clone();
    let scene = &mut old.scenes[0];
    scene.reference.values = None;
    scene.difference_scale = None;
    scene.flip = None;
    for m in scene.methods.iter_mut() {
        m.values = None;
        m.difference_map = None;
        (m.flip_mean, m.flip_se, m.flip_map) = (None, None, None);
        m.flip_per_seed.clear();
    }
    scene.convergence = (1..=3)
        .map(|k| cvtrace_eval::ConvergencePoint {
            method: "pt".into(),
            spp_total: 4 << k,
            relmse: 1.0 / k as f64,
            relmse_se: None,
            seconds: None,
            bias2: None,
        })
        .collect();
    let index = write_report(&old, &study, &dir.path().join("old"), &ReportOptions::default()).unwrap();
    assert!(!dir.path().join("old/images").join(&sl).join("pixels.js").exists());
    assert!(!dir.path().join(format!("old/plots/{sl}.time.svg")).exists());
    let dom = chromium(&dir.path().join("profile-old"), &["--dump-dom".to_string()], &file_url(&index));
    assert_eq!(attr(&dom, "<body", "data-ready").as_deref(), Some("1"), "viewer.js did not finish");
    assert!(dom.contains("carry no linear values"), "the readout says why it shows only the position");
    assert!(dom.contains("No times per point") && dom.contains("data-plot=\"spp\""), "the spp plot stays, the time plot is explained");
    assert!(!dom.contains("grid diffs"), "no difference view without difference maps");
    assert!(!dom.contains("grid flips") && !dom.contains("/flip_mean\""), "no FLIP view or column without FLIP");
}

/// Drives the page as a user would, from a script loaded after viewer.js: points at pixel
/// (`X`, `Y`) of the first scene's `ours` image (a pointer event at that pixel's centre), waits
/// for the readout to fill, and clicks the relMSE header twice. What it saw goes into the body's
/// data attributes, which `--dump-dom` prints.
const DRIVER: &str = r#"
"use strict";
(function () {
  const body = document.body;
  const sec = document.querySelector("section.scene");
  const vp = sec.querySelector('.grid.images .viewport[data-method="ours"]');
  const scene = window.CVTRACE_DATA.results.scenes[0];
  const r = vp.getBoundingClientRect();
  const at = { clientX: r.left + (X + 0.5) / scene.width * r.width, clientY: r.top + (Y + 0.5) / scene.height * r.height, bubbles: true };
  body.dataset.pixelsBefore = String(document.querySelectorAll('script[src*="pixels.js"]').length);
  vp.dispatchEvent(new PointerEvent("pointermove", at));
  const rows = () => [...sec.querySelectorAll("table.results:not(.readout-table):not(.settings) tbody tr.main")].map((tr) => tr.dataset.method).join(" ");
  const th = [...sec.querySelectorAll("table.results:not(.readout-table) th")].find((h) => h.textContent === "relMSE");
  th.click();
  body.dataset.sortAsc = rows();
  th.click();
  body.dataset.sortDesc = rows();
  let tries = 0;
  (function wait() {
    const cell = sec.querySelector('[data-key$="/pixel/ours/R"]');
    if (cell && cell.hasAttribute("data-value")) { body.dataset.driver = "done"; body.dataset.pixel = sec.dataset.pixel; return; }
    if (++tries > 200) { body.dataset.driver = "timeout"; return; }
    setTimeout(wait, 20);
  })();
})();
"#;

#[test]
fn viewer_pixel_readout_shows_the_exr_values_and_the_table_sorts() {
    if !have_chromium() {
        eprintln!("SKIPPED viewer_chromium: {CHROMIUM} not found.");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let study = dir.path().join("study");
    let results = two_scene_study(&study);
    let out = dir.path().join("report");
    write_report(&results, &study, &out, &ReportOptions::default()).unwrap();
    let scene = &results.scenes[0];
    let sl = slug(&scene.name);
    // Not symmetric, so swapped axes or a wrong row stride show other values.
    let (x, y) = (61usize, 17usize);
    assert!(x < scene.width && y < scene.height);
    std::fs::write(
        out.join("driver.js"),
        DRIVER.replace("(X + 0.5)", &format!("({x} + 0.5)")).replace("(Y + 0.5)", &format!("({y} + 0.5)")),
    )
    .unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    std::fs::write(out.join("driver.html"), html.replace("</body>", "<script src=\"driver.js\"></script>\n</body>")).unwrap();
    let dom = chromium(&dir.path().join("profile"), &["--dump-dom".to_string()], &file_url(&out.join("driver.html")));
    assert_eq!(attr(&dom, "<body", "data-driver").as_deref(), Some("done"), "the readout never filled");
    assert_eq!(attr(&dom, "<body", "data-pixels-before").as_deref(), Some("0"), "pixels.js loads on first use, not with the page");
    assert_eq!(attr(&dom, "<body", "data-pixel"), Some(format!("{x},{y}")), "the pointer event hit another pixel");
    let loaded = attr(&dom, "<body", "data-loaded").unwrap();
    assert!(loaded.split_once('/').is_some_and(|(a, b)| a == b), "images loaded: {loaded}");

    // 1. The readout shows every image's values at (x, y), exactly as the study's EXRs hold them.
    let i = y * scene.width + x;
    let mut images: Vec<(String, String)> = vec![("reference".into(), scene.reference.values.clone().unwrap())];
    images.extend(scene.methods.iter().map(|m| (m.name.clone(), m.values.clone().unwrap())));
    let mut distinct = std::collections::HashSet::new();
    for (key, file) in &images {
        let exr = cvtrace_streams::exr_io::ExrChannels::read(&study.join(file)).unwrap();
        let mut channels = vec![("R", "R"), ("G", "G"), ("B", "B")];
        if key != "reference" {
            channels.push(("relmse", "relmse"));
            channels.push(("flip", "flip"));
        }
        for (shown_as, channel) in channels {
            let want = exr.channels[channel][i];
            let k = format!("{sl}/pixel/{key}/{shown_as}");
            let got = attr(&dom, &format!("data-key=\"{k}\""), "data-value").unwrap_or_else(|| panic!("{k} has no value"));
            let got: f64 = got.parse().unwrap();
            assert_eq!(got as f32, want, "{k}: the page shows {got}, the EXR has {want}");
            assert_eq!(got, want as f64, "{k}: not an f32 value");
            assert_shows(&dom, &k, Some(want as f64));
            distinct.insert(want.to_bits());
        }
        // The reference has no relMSE or FLIP of its own.
        if key == "reference" {
            assert_eq!(cell(&dom, &format!("{sl}/pixel/reference/relmse")).as_deref(), Some("–"));
            assert_eq!(cell(&dom, &format!("{sl}/pixel/reference/flip")).as_deref(), Some("–"));
        }
    }
    assert!(distinct.len() > images.len(), "the images should differ at the pixel, or the check proves little");

    // 2. Sorting: the first click on relMSE orders the main methods ascending, the second reverses.
    let mut main: Vec<_> = scene.methods.iter().filter(|m| !m.ablation).collect();
    main.sort_by(|a, b| a.relmse_mean.total_cmp(&b.relmse_mean));
    let asc: Vec<&str> = main.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(attr(&dom, "<body", "data-sort-asc").unwrap(), asc.join(" "));
    let desc: Vec<&str> = asc.iter().rev().copied().collect();
    assert_eq!(attr(&dom, "<body", "data-sort-desc").unwrap(), desc.join(" "));

    // 3. relMSE against time beside relMSE against spp, for every scene.
    for s in &results.scenes {
        let sl = slug(&s.name);
        let plot = format!("plots/{sl}.time.svg");
        assert!(dom.contains(&format!("src=\"{plot}\"")) && dom.contains("data-plot=\"time\""), "no time plot for {sl}");
        let svg = std::fs::read_to_string(out.join(&plot)).unwrap();
        assert!(svg.contains("relMSE vs time") && svg.contains("seconds per image"), "{plot}");
        // Squared bias against spp wherever some method's estimate is positive.
        let bias = format!("plots/{sl}.bias.svg");
        let positive = s.convergence.iter().any(|p| p.bias2.is_some_and(|b| b > 0.0));
        assert_eq!(dom.contains(&format!("src=\"{bias}\"")), positive, "bias plot of {sl}");
        if positive {
            assert!(std::fs::read_to_string(out.join(&bias)).unwrap().contains("bias² vs spp"), "{bias}");
        }
    }

    // 4. The signed difference view: one map per main method, and its legend's symmetric scale.
    let diffs = scene.methods.iter().filter(|m| !m.ablation).count();
    let grid = &dom[dom.find("class=\"grid diffs\"").expect("no difference grid")..];
    let grid = &grid[..grid.find("</section>").unwrap_or(grid.len())];
    assert_eq!(grid.matches("data-kind=\"diff\"").count(), diffs, "difference maps");
    let max = scene.difference_scale.as_ref().unwrap().max_abs;
    assert_shows(&dom, &format!("{sl}/difference/max"), Some(max));
    assert_shows(&dom, &format!("{sl}/difference/min"), Some(-max));
    assert!(dom.contains("src=\"colorbar-diff.png\""));

    // 5. The FLIP view: one magma map per main method, beside the relMSE maps, with its legend.
    let grid = &dom[dom.find("class=\"grid flips\"").expect("no FLIP grid")..];
    let grid = &grid[..grid.find("</section>").unwrap_or(grid.len())];
    assert_eq!(grid.matches("data-kind=\"flip\"").count(), diffs, "FLIP maps");
    assert!(dom.find("class=\"grid maps\"").unwrap() < dom.find("class=\"grid flips\"").unwrap(), "FLIP maps follow the relMSE maps");
    assert!(dom.contains("src=\"colorbar-flip.png\""));
    let settings = cell(&dom, &format!("{sl}/flip/settings")).expect("FLIP legend");
    let f = scene.flip.as_ref().unwrap();
    assert!(settings.contains("magma") && settings.contains(&format!("{} exposures", f.num_exposures)), "{settings}");
}
