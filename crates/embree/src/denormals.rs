//! Flush-to-zero / denormals-are-zero for the calling thread.
//!
//! Embree recommends FTZ and DAZ in every thread that traces rays: denormal arithmetic
//! is up to ~100x slower on x86 and buys nothing visible in a renderer. The mode only
//! changes results that would have been denormal (|x| < 1.2e-38), and it is set in *every*
//! worker thread (also with a single thread), so output stays bit-identical for any
//! thread count: the renderer's determinism does not depend on it being on or off, only
//! on it being the same everywhere.

#[cfg(any(target_arch = "x86_64", target_arch = "x86"))]
mod imp {
    use core::arch::asm;

    /// MXCSR bit 15 (FTZ) and bit 6 (DAZ).
    const FTZ_DAZ: u32 = (1 << 15) | (1 << 6);

    fn read_mxcsr() -> u32 {
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr stores the 32-bit control register into `csr`, which we own.
        unsafe { asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack, preserves_flags)) };
        csr
    }

    pub fn set() {
        let csr = read_mxcsr() | FTZ_DAZ;
        // SAFETY: ldmxcsr loads a valid MXCSR value (the current one with two mode bits set).
        unsafe { asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack, preserves_flags, readonly)) };
    }

    pub fn enabled() -> bool {
        read_mxcsr() & FTZ_DAZ == FTZ_DAZ
    }
}

#[cfg(target_arch = "aarch64")]
mod imp {
    use core::arch::asm;

    /// FPCR bit 24 (FZ): flushes denormal inputs and outputs.
    const FZ: u64 = 1 << 24;

    fn read_fpcr() -> u64 {
        let v: u64;
        // SAFETY: reading the floating-point control register has no side effects.
        unsafe { asm!("mrs {}, fpcr", out(reg) v, options(nomem, nostack, preserves_flags)) };
        v
    }

    pub fn set() {
        let v = read_fpcr() | FZ;
        // SAFETY: writes FPCR with only the FZ mode bit added.
        unsafe { asm!("msr fpcr, {}", in(reg) v, options(nomem, nostack, preserves_flags)) };
    }

    pub fn enabled() -> bool {
        read_fpcr() & FZ == FZ
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "x86", target_arch = "aarch64")))]
mod imp {
    pub fn set() {}
    pub fn enabled() -> bool {
        false
    }
}

/// Enables flush-to-zero and denormals-are-zero in the calling thread (a no-op on
/// architectures without a known control register). Call it at the start of every
/// thread that renders, e.g. in rayon's `start_handler`.
pub fn set_flush_denormals() {
    imp::set();
}

/// Whether the calling thread flushes denormals (for tests and diagnostics).
pub fn flush_denormals_enabled() -> bool {
    imp::enabled()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::hint::black_box;

    #[test]
    #[cfg(any(target_arch = "x86_64", target_arch = "x86", target_arch = "aarch64"))]
    fn denormal_results_flush_to_zero_only_in_the_thread_that_asked() {
        let tiny = f32::MIN_POSITIVE; // smallest normal; half of it is denormal
        let before = std::thread::spawn(move || black_box(tiny) * black_box(0.5)).join().unwrap();
        assert!(before > 0.0, "a fresh thread keeps IEEE denormals");
        let after = std::thread::spawn(move || {
            set_flush_denormals();
            assert!(flush_denormals_enabled());
            black_box(tiny) * black_box(0.5)
        })
        .join()
        .unwrap();
        assert_eq!(after, 0.0);
        // Normal numbers are untouched.
        let normal = std::thread::spawn(move || {
            set_flush_denormals();
            black_box(tiny) * black_box(2.0)
        })
        .join()
        .unwrap();
        assert_eq!(normal, tiny * 2.0);
    }
}
