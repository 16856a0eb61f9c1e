//! Times HDR-FLIP on a rendered-like image pair: a smooth HDR gradient with highlights and its
//! noisy estimate, at any size (default 1920x1080), with the threads rayon is given
//! (`RAYON_NUM_THREADS`).
//!
//!     cargo run --release -p cvtrace-eval --example flip_timing -- 1920 1080
use cvtrace_eval::flip::FlipReference;
use cvtrace_streams::Image;
use std::time::Instant;

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().expect("width and height in pixels")).collect();
    let (w, h) = (args.first().copied().unwrap_or(1920), args.get(1).copied().unwrap_or(1080));
    let reference = Image::from_fn(w, h, |x, y| {
        let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
        let light = 4.0 * (-3.0 * ((u - 0.3).powi(2) + (v - 0.2).powi(2))).exp() + 0.02;
        let lamp = if (x % 200 < 6) && (y % 150 < 6) { 80.0 } else { 0.0 };
        [light * 0.9 + lamp, light * 0.8 * (0.6 + 0.4 * u) + lamp, light * (0.5 + 0.5 * v) + lamp]
    });
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut noise = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    };
    let test = Image { pixels: reference.pixels.iter().map(|p| p.map(|c| c * (1.0 + 0.8 * noise()))).collect(), ..reference.clone() };
    let t0 = Instant::now();
    let fr = FlipReference::new(&reference, "reference").unwrap();
    let map = fr.evaluate(&test, "test").unwrap();
    let s = t0.elapsed().as_secs_f64();
    let e = fr.exposures();
    println!(
        "{w}x{h}, {} threads: {} exposures ({:.3} to {:.3}), mean FLIP {:.6}, {s:.3} s ({:.3} s per exposure)",
        rayon::current_num_threads(),
        e.count,
        e.start,
        e.stop,
        map.mean,
        s / e.count as f64
    );
}
