//! Samples per second of wall time and per CPU-second, for the render log.
//!
//! Why both: wall-clock rates depend on how many cores the machine lends the process, while
//! samples per CPU-second (process CPU time, all threads) compare across machines, thread counts
//! and renderers; docs/performance.md uses them.
use std::time::{Duration, Instant};

/// CPU time used by this process so far, over all its threads.
pub fn process_cpu_time() -> Option<Duration> {
    cpu_time::ProcessTime::try_now().ok().map(|t| t.as_duration())
}

/// The wall and CPU clocks at the start of a phase.
pub struct PhaseClock {
    wall: Instant,
    cpu: Option<Duration>,
}

impl PhaseClock {
    pub fn start() -> PhaseClock {
        PhaseClock { wall: Instant::now(), cpu: process_cpu_time() }
    }

    /// Logs `samples` over the phase so far: seconds, M samples/s and M samples per CPU-second.
    pub fn log_rate(&self, phase: &str, samples: u64) {
        let secs = self.wall.elapsed().as_secs_f64();
        let per_second = |s: f64| if s > 0.0 { samples as f64 / s / 1e6 } else { 0.0 };
        match process_cpu_time().zip(self.cpu).map(|(now, then)| now.saturating_sub(then).as_secs_f64()) {
            Some(cpu) => tracing::info!(
                "{phase}: {samples} samples in {secs:.2} s ({:.2} M samples/s; {cpu:.2} CPU-s, {:.2} M samples per CPU-second)",
                per_second(secs),
                per_second(cpu)
            ),
            None => tracing::info!("{phase}: {samples} samples in {secs:.2} s ({:.2} M samples/s)", per_second(secs)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_time_advances_with_work_and_not_with_sleep() {
        // Spinning must make the clock advance by 50 ms however small a share of a core the
        // machine gives this process (a loaded CI runner gives a fraction); 10 s of wall time
        // without it means the clock does not count work.
        let before = process_cpu_time().expect("Linux has a process CPU clock");
        let mut x = 0u64;
        let start = Instant::now();
        while process_cpu_time().unwrap() - before < Duration::from_millis(50) {
            assert!(start.elapsed() < Duration::from_secs(10), "10 s of spinning counted as less than 50 ms of CPU");
            for _ in 0..10_000 {
                x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
            }
        }
        let before = process_cpu_time().unwrap();
        std::thread::sleep(Duration::from_millis(100));
        let idle = process_cpu_time().unwrap() - before;
        assert!(idle < Duration::from_millis(50), "a 100 ms sleep counted as {idle:?} of CPU");
    }
}
