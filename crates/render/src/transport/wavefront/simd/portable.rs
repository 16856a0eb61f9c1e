//! The kernel for any CPU: the transpose as plain swaps, and whatever the compiler makes of the
//! lane loops for the target's baseline instructions.
use super::super::lanes::{shade, Blocks, Chunk, Consts, Out, Record, Transpose, W};

/// The build every CPU runs.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Portable;

impl Transpose for Portable {
    #[inline(always)]
    fn transpose(self, block: &mut [Record; W]) {
        for j in 1..W {
            let (upper, lower) = block.split_at_mut(j);
            for (i, row) in upper.iter_mut().enumerate() {
                std::mem::swap(&mut row[j], &mut lower[0][i]);
            }
        }
    }
}

impl Portable {
    /// The kernel (see [`shade`]), compiled once, outside its callers.
    #[inline(never)]
    pub fn run(self, c: &mut Chunk, o: &mut Out, b: &mut Blocks, normals: bool, k: &Consts) {
        shade(self, c, o, b, normals, k)
    }
}
