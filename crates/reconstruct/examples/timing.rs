//! Times each estimator on one synthetic stream set (default 1280×720, B = 16):
//! `cargo run --release -p cvtrace-reconstruct --example timing -- [width height batches methods]`
//! (`TIMING_REPEATS=N` runs the methods N times in turn; `TIMING_DUMP=DIR` writes each method's
//! image, layers and diagnostics as raw bits to `DIR/<method>.bin`, to compare two builds).
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::{Input, Overrides, Registry};
use std::time::Instant;

fn main() {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: usize| a.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (w, h, b) = (arg(0, 1280), arg(1, 720), arg(2, 16));
    let registry = Registry::builtin();
    let methods = registry.select(a.get(3).map(String::as_str).unwrap_or("all")).unwrap();
    let t = Instant::now();
    let set = SoftShadowScene::default().render(&RenderSpec { width: w, height: h, spp: b as u32, batches: b, seed: 1 }).unwrap();
    println!("rendered {w}x{h} B={b} in {:.2}s on {} threads", t.elapsed().as_secs_f64(), rayon::current_num_threads());
    if std::env::var_os("IDUW_SPLIT").is_some() {
        iduw_split(&set);
    }
    // TIMING_REPEATS=N runs every method N times in turn on the same set.
    let repeats: usize = std::env::var("TIMING_REPEATS").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    for spec in (0..repeats).flat_map(|_| methods.iter()) {
        let e = registry.build(spec.name, &Overrides::default()).unwrap();
        let cpu0 = cpu_seconds();
        let out = e.run(&Input::new(&set)).unwrap();
        let s = out.diagnostics.seconds;
        let cpu = cpu_seconds().map(|c| c - cpu0.unwrap_or(0.0)).unwrap_or(f64::NAN);
        let phase = |key: &str, label: &str| out.diagnostics.get(key).map(|v| format!("  ({label} {v:.3} s)")).unwrap_or_default();
        let prep = phase("seconds_prepare", "prepare") + &phase("seconds_gamma", "γ criterion");
        if let Some(dir) = std::env::var_os("TIMING_DUMP") {
            dump(&std::path::Path::new(&dir).join(format!("{}.bin", spec.name)), &out);
        }
        println!("{:<8} {:>7.3} s wall {:>7.3} s cpu  {:>7.2} Mpix/s{prep}", spec.name, s, cpu, (w * h) as f64 / s / 1e6);
    }
}

/// IDUW's cost split: the γ selection versus the final pass (fixed γ).
fn iduw_split(set: &cvtrace_reconstruct::StreamSet) {
    let fixed = cvtrace_reconstruct::build("iduw", &Overrides::parse(["iduw.gamma=2.5"]).unwrap()).unwrap();
    let out = fixed.run(&Input::new(set)).unwrap();
    println!("iduw-fixed {:>7.3} s wall (final pass only)", out.diagnostics.seconds);
}

/// Process CPU time (user + system) from /proc, to judge timings on a busy machine.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let fields: Vec<&str> = stat.rsplit(')').next()?.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// The output's bits: image, then each layer, then the diagnostics but their timings.
fn dump(path: &std::path::Path, out: &cvtrace_reconstruct::Output) {
    let mut bytes = Vec::new();
    for im in std::iter::once(&out.image).chain(out.aovs.iter().map(|(_, a)| a)) {
        for p in &im.pixels {
            for v in p {
                bytes.extend_from_slice(&v.to_bits().to_le_bytes());
            }
        }
    }
    for (name, v) in out.diagnostics.entries.iter().filter(|(n, _)| !n.starts_with("seconds")) {
        bytes.extend_from_slice(format!("{name}={v:?}\n").as_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}
