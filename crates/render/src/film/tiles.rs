//! Image tiles and their accumulation buffers.
//!
//! Each tile is rendered independently into its own buffers and then copied into the image,
//! so per-pixel sums never depend on which thread ran which tile. A batch's sum is kept in f64
//! and accumulated in sample-index order; the totals over all samples are exact fixed-point
//! sums ([`cvtrace_streams::exact`]), so any split of the batches adds up to the same total.
use cvtrace_streams::exact;
use glam::{DVec3, Vec3A};

/// Tile edge length in pixels: small enough to balance 2 cores, large enough to amortise overhead.
pub const TILE_SIZE: u32 = 16;

/// A rectangle of pixels `[x0, x0 + w) × [y0, y0 + h)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub w: u32,
    pub h: u32,
}

impl Tile {
    pub fn pixel_count(&self) -> usize {
        self.w as usize * self.h as usize
    }

    /// Pixels of the tile in row-major order as `(x, y)`.
    pub fn pixels(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        (self.y0..self.y0 + self.h).flat_map(move |y| (self.x0..self.x0 + self.w).map(move |x| (x, y)))
    }
}

/// The tiles covering a `width`×`height` image, row by row.
pub fn tiles(width: u32, height: u32) -> Vec<Tile> {
    let mut out = Vec::new();
    for y0 in (0..height).step_by(TILE_SIZE as usize) {
        for x0 in (0..width).step_by(TILE_SIZE as usize) {
            out.push(Tile { x0, y0, w: TILE_SIZE.min(width - x0), h: TILE_SIZE.min(height - y0) });
        }
    }
    out
}

/// One stream of one pixel: the running total over all samples and the current batch's sum.
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelSums {
    pub total: [i128; 3],
    pub batch: DVec3,
}

impl PixelSums {
    #[inline]
    pub fn add(&mut self, v: Vec3A) {
        exact::add3(&mut self.total, exact::fixed3(v.to_array()));
        self.batch += v.as_dvec3();
    }

    /// Ends the current batch of `n` samples, returning its mean.
    #[inline]
    pub fn take_batch_mean(&mut self, n: u32) -> [f32; 3] {
        let m = (self.batch / n as f64).as_vec3();
        self.batch = DVec3::ZERO;
        m.to_array()
    }
}

/// One stream's results for the pixels of one tile.
#[derive(Clone, Debug, Default)]
pub struct TileStream {
    /// Exact sums of the pixels' samples in the rendered batches.
    pub sum: Vec<[i128; 3]>,
    /// `batches[b][i]`: batch `b` of the tile's pixel `i`.
    pub batches: Vec<Vec<[f32; 3]>>,
}

impl TileStream {
    pub fn new(pixels: usize, batches: usize) -> TileStream {
        TileStream { sum: Vec::with_capacity(pixels), batches: (0..batches).map(|_| Vec::with_capacity(pixels)).collect() }
    }
}

/// Everything a tile produces for a stream render.
#[derive(Clone, Debug)]
pub struct TileResult {
    pub tile: Tile,
    pub pt: TileStream,
    pub crn: TileStream,
    /// Exact sums of the first-hit features over the PT samples.
    pub albedo: Vec<[i128; 3]>,
    pub normal: Vec<[i128; 3]>,
    pub depth: Vec<i128>,
    pub non_finite: u64,
}
