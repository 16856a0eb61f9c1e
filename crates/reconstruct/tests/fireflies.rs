//! A firefly in one PT pixel: `ours` must not trust that pixel. Its CBF error estimate keeps the
//! pixel's own (huge) batch variance by default; leaving it out, as cvtrace did before issue 5's
//! study, estimates the error from the quiet neighbours alone and lets the firefly through.
mod common;

use common::{normal, stream_set};
use cvtrace_reconstruct::estimators::ImperfectCv;
use cvtrace_reconstruct::{Estimator, ImperfectCvOptions, Input, StreamSet};

const W: usize = 21;
const TRUTH: f64 = 0.5;
const SIGMA: f64 = 0.05;
const BATCHES: usize = 16;
/// One batch of the centre pixel carries a sample this much too bright (its batch mean).
const FIREFLY: f64 = 40.0;

fn centre() -> usize {
    (W / 2) * W + W / 2
}

/// Flat image; PT noise independent per pixel and batch, CRN noise shared by all pixels.
fn set_with_firefly() -> StreamSet {
    stream_set(
        W,
        W,
        BATCHES,
        64,
        |_| TRUTH,
        |b, _| SIGMA * normal(2, b as u64),
        |b, i| SIGMA * normal(1, (b * W * W + i) as u64) + if i == centre() && b == 3 { FIREFLY } else { 0.0 },
    )
}

fn centre_output(exclude_centre: bool) -> (f64, f64) {
    let mut o = ImperfectCvOptions::default();
    o.cbf.exclude_centre = exclude_centre;
    let set = set_with_firefly();
    let out = ImperfectCv::new(o).unwrap().reconstruct(&Input::new(&set)).unwrap();
    (out.image.pixels[centre()][1] as f64, set.pt.mean.pixels[centre()][1] as f64)
}

#[test]
fn a_firefly_pixel_is_not_trusted_by_default() {
    assert!(!ImperfectCvOptions::default().cbf.exclude_centre, "the default keeps the centre in its CBF estimate");
    let (out, pt) = centre_output(false);
    // The PT mean carries FIREFLY / BATCHES = 2.5 of error; the neighbours' PT values and the
    // CRN difference give the centre back to within a few of the neighbours' noise levels.
    assert!((pt - TRUTH).abs() > 2.0, "the input has its firefly: {pt}");
    assert!((out - TRUTH).abs() < 0.1, "the firefly survived: output {out}, PT {pt}");
}

#[test]
fn leaving_the_centre_out_lets_the_firefly_through() {
    let (out, pt) = centre_output(true);
    // The centre's estimate comes from quiet-ish neighbours only (theirs include the firefly's
    // variance), so its PT value is largely trusted: measured 37% of the firefly's error is
    // kept, against under 4% (0.1 of 2.5) with the default.
    assert!((out - TRUTH).abs() > 0.25 * (pt - TRUTH).abs(), "output {out}, PT {pt}");
}
