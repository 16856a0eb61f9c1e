//! Progress on the terminal: a bar per render on stderr, drawn only when stderr is a terminal,
//! with the rate in millions of samples per second (what renderers quote).
use cvtrace_session::Progress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::sync::OnceLock;

/// A progress bar on stderr, drawn only when stderr is a terminal; one per render.
#[derive(Default)]
pub struct TerminalProgress {
    bar: OnceLock<ProgressBar>,
}

impl Progress for TerminalProgress {
    fn start(&self, total: u64, done: u64) {
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
        bar.set_style(progress_style_of(PROGRESS_TEMPLATE));
        bar.set_position(done);
        bar.reset_eta();
        let _ = self.bar.set(bar);
    }

    fn advance(&self, samples: u64) {
        // Interrupted, the process is ending: a bar drawn now would land after the note.
        if cvtrace_streams::atomic::interrupted() {
            return;
        }
        if let Some(bar) = self.bar.get() {
            bar.inc(samples);
        }
    }

    fn suspend(&self, f: &mut dyn FnMut()) {
        match self.bar.get() {
            Some(bar) => bar.suspend(f),
            None => f(),
        }
    }

    fn finish(&self) {
        if let Some(bar) = self.bar.get() {
            bar.finish_and_clear();
        }
    }
}

/// The render progress line: at most [`PROGRESS_COLUMNS`] wide whatever the numbers, with the
/// rate in millions of samples per second (what renderers quote).
pub const PROGRESS_TEMPLATE: &str = "{elapsed_precise} [{bar:24.cyan/blue}] {percent:>3}% {msamples} M, {rate} M samples/s, ETA {eta}";
#[cfg(test)]
pub const PROGRESS_COLUMNS: usize = 80;

/// `template` with the widest values its keys take: hours of elapsed time, a full bar, 100%,
/// 10^11 samples done at 10^11 samples/s, and a 4-character ETA (indicatif's "59m", "23h").
#[cfg(test)]
pub fn widest_progress_line(template: &str) -> String {
    let bar = regex_lite_bar(template);
    template
        .replace("{elapsed_precise}", "99:59:59")
        .replace(&bar.0, &"#".repeat(bar.1))
        .replace("{percent:>3}", "100")
        .replace("{msamples}", &millions(1e11))
        .replace("{rate}", &millions(1e11))
        .replace("{eta}", "999d")
}

/// The `{bar:N...}` key of `template` and its width N.
#[cfg(test)]
fn regex_lite_bar(template: &str) -> (String, usize) {
    let start = template.find("{bar:").expect("a bar");
    let end = start + template[start..].find('}').expect("a closed key") + 1;
    let key = &template[start..end];
    let width = key[5..].split('.').next().and_then(|w| w.parse().ok()).expect("a bar width");
    (key.to_string(), width)
}

/// `template` (with the keys `{msamples}`, done, and `{rate}`, both in millions) as a style.
pub fn progress_style_of(template: &str) -> ProgressStyle {
    ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .with_key("msamples", |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&millions(s.pos() as f64));
        })
        .with_key("rate", |s: &indicatif::ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&millions(s.per_sec()));
        })
}

/// `x` in millions with 3 or 4 significant digits, at most 6 characters below 10^12.
fn millions(x: f64) -> String {
    let m = x / 1e6;
    if !m.is_finite() || m < 0.0 {
        "?".into()
    } else if m < 10.0 {
        format!("{m:.2}")
    } else if m < 1000.0 {
        format!("{m:.1}")
    } else {
        format!("{m:.0}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_progress_line_fits_80_columns_and_reads_in_millions() {
        assert_eq!(
            (millions(1.234e6), millions(45.67e6), millions(999.94e6), millions(123_456.0e6)),
            ("1.23".into(), "45.7".into(), "999.9".into(), "123456".into())
        );
        let widest = widest_progress_line(PROGRESS_TEMPLATE);
        assert!(!widest.contains('{'), "every key is replaced: {widest}");
        assert!(widest.contains("M samples/s"), "{widest}");
        assert!(widest.chars().count() <= PROGRESS_COLUMNS, "{} columns: {widest}", widest.chars().count());
        // The template is one indicatif accepts (else the plain bar would be drawn).
        assert!(ProgressStyle::with_template(PROGRESS_TEMPLATE).is_ok());
    }
}
