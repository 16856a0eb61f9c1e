//! The lane kernel's three builds ([`lanes::shade`](super::lanes::shade) compiled for AVX-512,
//! for AVX2 and for any CPU), and the choice between them. Every build does the same IEEE
//! operations in the same order, so all three give the same bits.
//!
//! A build for an instruction set is reached only through its token ([`avx512::Avx512`],
//! [`avx2::Avx2`]), a value that only CPU-feature detection makes: holding one proves that the
//! CPU runs the instructions its functions are compiled for, so they can be safe functions. The
//! `unsafe` blocks that the proof stands behind (calling `#[target_feature]` code, the
//! intrinsics) are in these files and nowhere else in the crate.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2;
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx512;
pub(crate) mod portable;

use super::lanes::{Blocks, Chunk, Consts, Out};
#[cfg(target_arch = "x86_64")]
use avx2::Avx2;
#[cfg(target_arch = "x86_64")]
use avx512::Avx512;
use portable::Portable;

/// A build of the kernel this CPU runs: shades the lanes of a chunk whose `shade` is set, from
/// the records the caller copied into the blocks (which it transposes in place; vertex normals
/// only if `normals`).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Kernel {
    Portable(Portable),
    #[cfg(target_arch = "x86_64")]
    Avx2(Avx2),
    #[cfg(target_arch = "x86_64")]
    Avx512(Avx512),
}

impl Kernel {
    #[inline]
    pub fn run(self, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
        match self {
            Kernel::Portable(isa) => isa.run(c, o, b, normals, k),
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2(isa) => isa.run(c, o, b, normals, k),
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512(isa) => isa.run(c, o, b, normals, k),
        }
    }
}

/// Which build of the kernel runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Isa {
    Avx512,
    Avx2,
    Portable,
}

impl Isa {
    /// The widest build this CPU runs.
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if Avx512::detect().is_some() {
                return Isa::Avx512;
            }
            if Avx2::detect().is_some() {
                return Isa::Avx2;
            }
        }
        Isa::Portable
    }

    /// The kernel of this build, or `None` if the CPU lacks its instructions.
    pub fn kernel(self) -> Option<Kernel> {
        match self {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => Avx512::detect().map(Kernel::Avx512),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => Avx2::detect().map(Kernel::Avx2),
            #[cfg(not(target_arch = "x86_64"))]
            Isa::Avx512 | Isa::Avx2 => None,
            Isa::Portable => Some(Kernel::Portable(Portable)),
        }
    }
}
