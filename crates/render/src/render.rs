//! The render driver: paired PT/CRN stream renders and progressive PT reference renders,
//! parallel over tiles with rayon and bit-identical for any thread count.
//!
//! For each pixel and each stream, samples `0..spp` are split into `batches` contiguous ranges
//! of `spp / batches` samples (the same ranges in every pixel and both streams); each batch
//! mean and the stream mean are stored. The pixel filter is a box: a sample only counts in the
//! pixel it was taken in.
use crate::camera::CameraFrame;
use crate::film::{tiles, PixelSums, Tile, TileResult, TileStream};
use crate::integrator::{radiance, FirstHit, PathLimits};
use crate::intersect::Intersector;
use crate::sampler::{dims, StreamKind, StreamSampler};
use crate::scene::Scene;
use cvtrace_streams::{Features, Image, Stream, StreamMeta, StreamSet};
use glam::{DVec3, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// Largest accepted image side.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// What to render. `spp` is per stream; `max_depth` follows Mitsuba (−1 unlimited, see
/// [`crate::integrator`]); Russian roulette starts at depth `rr_depth`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub batches: u32,
    pub seed: u64,
    pub max_depth: i32,
    pub rr_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings { width: 512, height: 512, spp: 64, batches: 4, seed: 0, max_depth: -1, rr_depth: 5 }
    }
}

/// Why a render could not run.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("invalid render settings: {0}")]
    InvalidSettings(String),
    #[error("the scene's camera is unusable: {0}")]
    Camera(String),
    #[error("reference accumulator does not match: {0}")]
    ReferenceMismatch(String),
}

impl RenderSettings {
    /// Checks image size, path-length limits and the batch split.
    pub fn validate(&self) -> Result<(), RenderError> {
        self.validate_image()?;
        let bad = |m: String| Err(RenderError::InvalidSettings(m));
        if self.spp == 0 {
            return bad("spp must be at least 1".into());
        }
        if self.batches == 0 {
            return bad("batches must be at least 1".into());
        }
        if !self.spp.is_multiple_of(self.batches) {
            return bad(format!("spp ({}) must be a multiple of batches ({})", self.spp, self.batches));
        }
        Ok(())
    }

    /// The checks that also apply to reference renders (which ignore `spp` and `batches`).
    fn validate_image(&self) -> Result<(), RenderError> {
        let bad = |m: String| Err(RenderError::InvalidSettings(m));
        if self.width == 0 || self.height == 0 || self.width > MAX_IMAGE_SIDE || self.height > MAX_IMAGE_SIDE {
            return bad(format!("image size {}x{} must be between 1 and {MAX_IMAGE_SIDE} on each side", self.width, self.height));
        }
        if self.max_depth < -1 || self.max_depth == 0 {
            return bad(format!("max_depth {} must be -1 (unlimited) or at least 1", self.max_depth));
        }
        Ok(())
    }

    fn limits(&self) -> PathLimits {
        PathLimits { max_depth: self.max_depth, rr_depth: self.rr_depth }
    }
}

/// Shared, read-only state of one render.
struct Context<'a, T: Intersector> {
    scene: &'a Scene,
    tracer: &'a T,
    frame: CameraFrame,
    limits: PathLimits,
    width: u32,
}

impl<T: Intersector> Context<'_, T> {
    /// One sample of pixel `(x, y)`; non-finite results are replaced by zero and reported.
    #[inline]
    fn sample(&self, stream: &StreamSampler, x: u32, y: u32, s: u32, first: Option<&mut FirstHit>) -> (Vec3, bool) {
        let pixel = y as u64 * self.width as u64 + x as u64;
        let smp = stream.sample(pixel, s);
        let ray = self.frame.ray(x, y, smp.get2d(dims::PIXEL));
        let v = radiance(self.scene, self.tracer, self.limits, ray, &smp, first);
        if v.is_finite() {
            (v, false)
        } else {
            (Vec3::ZERO, true)
        }
    }
}

fn context<'a, T: Intersector>(scene: &'a Scene, tracer: &'a T, settings: &RenderSettings) -> Result<Context<'a, T>, RenderError> {
    scene.camera().validate().map_err(RenderError::Camera)?;
    if scene.lights().is_empty() {
        tracing::warn!("the scene has no lights (emissive surfaces, glTF lights or a sidecar environment): the image will be black");
    }
    Ok(Context {
        scene,
        tracer,
        frame: scene.camera().frame(settings.width, settings.height),
        limits: settings.limits(),
        width: settings.width,
    })
}

/// Renders the paired PT and CRN streams with `settings.spp` samples each, plus first-hit
/// features averaged over the PT samples. `progress(k)` is called as `k` more
/// pixel-samples (over both streams) complete. `meta.scene` is left empty for the caller.
pub fn render_streams<T: Intersector>(
    scene: &Scene,
    tracer: &T,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<StreamSet, RenderError> {
    settings.validate()?;
    let ctx = context(scene, tracer, settings)?;
    let pt = StreamSampler::new(settings.seed, StreamKind::Pt);
    let crn = StreamSampler::new(settings.seed, StreamKind::Crn);
    let (spp, nb) = (settings.spp, settings.batches);
    let per_batch = spp / nb;

    let render_tile = |tile: &Tile| -> TileResult {
        let n = tile.pixel_count();
        let mut r = TileResult {
            tile: *tile,
            pt: TileStream::new(n, nb as usize),
            crn: TileStream::new(n, nb as usize),
            albedo: Vec::with_capacity(n),
            normal: Vec::with_capacity(n),
            depth: Vec::with_capacity(n),
            non_finite: 0,
        };
        for (x, y) in tile.pixels() {
            // PT with features.
            let mut sums = PixelSums::default();
            let (mut albedo, mut normal, mut depth) = (DVec3::ZERO, DVec3::ZERO, 0.0f64);
            for s in 0..spp {
                let mut fh = FirstHit::default();
                let (v, bad) = ctx.sample(&pt, x, y, s, Some(&mut fh));
                r.non_finite += bad as u64;
                sums.add(v);
                albedo += fh.albedo.as_dvec3();
                normal += fh.normal.as_dvec3();
                depth += fh.depth as f64;
                if (s + 1) % per_batch == 0 {
                    r.pt.batches[(s / per_batch) as usize].push(sums.take_batch_mean(per_batch));
                }
            }
            r.pt.mean.push((sums.total / spp as f64).as_vec3().to_array());
            let inv = 1.0 / spp as f64;
            r.albedo.push((albedo * inv).as_vec3().to_array());
            r.normal.push((normal * inv).as_vec3().to_array());
            r.depth.push((depth * inv) as f32);
            // CRN.
            let mut sums = PixelSums::default();
            for s in 0..spp {
                let (v, bad) = ctx.sample(&crn, x, y, s, None);
                r.non_finite += bad as u64;
                sums.add(v);
                if (s + 1) % per_batch == 0 {
                    r.crn.batches[(s / per_batch) as usize].push(sums.take_batch_mean(per_batch));
                }
            }
            r.crn.mean.push((sums.total / spp as f64).as_vec3().to_array());
        }
        progress(n as u64 * spp as u64 * 2);
        r
    };
    let results: Vec<TileResult> = tiles(settings.width, settings.height).par_iter().map(render_tile).collect();

    let (w, h) = (settings.width as usize, settings.height as usize);
    let blank = || Image::new(w, h);
    let mut pt_mean = blank();
    let mut crn_mean = blank();
    let mut pt_batches: Vec<Image> = (0..nb).map(|_| blank()).collect();
    let mut crn_batches: Vec<Image> = (0..nb).map(|_| blank()).collect();
    let mut albedo = blank();
    let mut normal = blank();
    let mut depth = vec![0.0f32; w * h];
    let mut non_finite = 0u64;
    for r in &results {
        let tile = r.tile;
        non_finite += r.non_finite;
        for (i, (x, y)) in tile.pixels().enumerate() {
            let p = y as usize * w + x as usize;
            pt_mean.pixels[p] = r.pt.mean[i];
            crn_mean.pixels[p] = r.crn.mean[i];
            for b in 0..nb as usize {
                pt_batches[b].pixels[p] = r.pt.batches[b][i];
                crn_batches[b].pixels[p] = r.crn.batches[b][i];
            }
            albedo.pixels[p] = r.albedo[i];
            normal.pixels[p] = r.normal[i];
            depth[p] = r.depth[i];
        }
    }
    if non_finite > 0 {
        tracing::warn!("{non_finite} samples were NaN or infinite and were replaced by zero");
    }
    Ok(StreamSet {
        width: w,
        height: h,
        pt: Stream { mean: pt_mean, batches: pt_batches },
        crn: Stream { mean: crn_mean, batches: crn_batches },
        features: Some(Features { albedo, normal, depth }),
        meta: StreamMeta {
            spp,
            seed: settings.seed,
            max_depth: settings.max_depth,
            scene: String::new(),
            version: env!("CARGO_PKG_VERSION").to_string(),
            non_finite_samples: non_finite,
            settings: Default::default(),
        },
    })
}

/// Running sums of a progressive PT reference render. Samples are added to each pixel's f64
/// sum in sample-index order, so N samples give bit-identical results however the render is
/// split into passes, and equal the PT stream mean of [`render_streams`] at the same seed.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceAccum {
    pub width: u32,
    pub height: u32,
    pub sum: Vec<[f64; 3]>,
    pub samples_done: u32,
    pub seed: u64,
    pub max_depth: i32,
    pub rr_depth: u32,
    pub non_finite_samples: u64,
}

impl ReferenceAccum {
    /// An empty accumulator for `settings` (its resolution, seed and path limits).
    pub fn new(settings: &RenderSettings) -> ReferenceAccum {
        ReferenceAccum {
            width: settings.width,
            height: settings.height,
            sum: vec![[0.0; 3]; settings.width as usize * settings.height as usize],
            samples_done: 0,
            seed: settings.seed,
            max_depth: settings.max_depth,
            rr_depth: settings.rr_depth,
            non_finite_samples: 0,
        }
    }

    /// Resumes from a saved mean image of `samples_done` samples. The sums are rebuilt from f32
    /// means, so a resumed reference matches an uninterrupted one only to f32 rounding.
    pub fn from_mean(settings: &RenderSettings, mean: &Image, samples_done: u32) -> Result<ReferenceAccum, RenderError> {
        if mean.width != settings.width as usize || mean.height != settings.height as usize {
            return Err(RenderError::ReferenceMismatch(format!(
                "saved reference is {}x{}, the render is {}x{}",
                mean.width, mean.height, settings.width, settings.height
            )));
        }
        let mut acc = ReferenceAccum::new(settings);
        let n = samples_done as f64;
        for (s, m) in acc.sum.iter_mut().zip(&mean.pixels) {
            *s = [m[0] as f64 * n, m[1] as f64 * n, m[2] as f64 * n];
        }
        acc.samples_done = samples_done;
        Ok(acc)
    }

    /// The mean of the samples so far (black before the first pass).
    pub fn mean(&self) -> Image {
        let (w, h) = (self.width as usize, self.height as usize);
        if self.samples_done == 0 {
            return Image::new(w, h);
        }
        let n = self.samples_done as f64;
        Image { width: w, height: h, pixels: self.sum.iter().map(|s| [(s[0] / n) as f32, (s[1] / n) as f32, (s[2] / n) as f32]).collect() }
    }
}

/// Adds PT samples `sample_range` of every pixel to `accum` (the range must start at
/// `accum.samples_done`). Sample `s` uses the same random numbers as sample `s` of the PT
/// stream in [`render_streams`]. `progress(k)`: `k` more pixel-samples done.
pub fn render_reference_pass<T: Intersector>(
    scene: &Scene,
    tracer: &T,
    settings: &RenderSettings,
    accum: &mut ReferenceAccum,
    sample_range: Range<u32>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(), RenderError> {
    settings.validate_image()?;
    let mismatch = |m: String| Err(RenderError::ReferenceMismatch(m));
    if (accum.width, accum.height) != (settings.width, settings.height) {
        return mismatch(format!(
            "accumulator is {}x{}, settings ask for {}x{}",
            accum.width, accum.height, settings.width, settings.height
        ));
    }
    if accum.sum.len() != settings.width as usize * settings.height as usize {
        return mismatch(format!("accumulator holds {} pixels, expected {}", accum.sum.len(), settings.width * settings.height));
    }
    if (accum.seed, accum.max_depth, accum.rr_depth) != (settings.seed, settings.max_depth, settings.rr_depth) {
        return mismatch(format!(
            "accumulator has seed {}, max_depth {}, rr_depth {}; settings have {}, {}, {}",
            accum.seed, accum.max_depth, accum.rr_depth, settings.seed, settings.max_depth, settings.rr_depth
        ));
    }
    if sample_range.start != accum.samples_done {
        return mismatch(format!("pass starts at sample {} but {} samples are done", sample_range.start, accum.samples_done));
    }
    if sample_range.end <= sample_range.start {
        return Err(RenderError::InvalidSettings(format!("empty sample range {sample_range:?}")));
    }
    let ctx = context(scene, tracer, settings)?;
    let pt = StreamSampler::new(settings.seed, StreamKind::Pt);
    let width = settings.width as usize;
    let sums = &accum.sum;
    let results: Vec<(Tile, Vec<[f64; 3]>, u64)> = tiles(settings.width, settings.height)
        .par_iter()
        .map(|tile| {
            let mut out = Vec::with_capacity(tile.pixel_count());
            let mut bad_count = 0u64;
            for (x, y) in tile.pixels() {
                let mut s = DVec3::from_array(sums[y as usize * width + x as usize]);
                for i in sample_range.clone() {
                    let (v, bad) = ctx.sample(&pt, x, y, i, None);
                    bad_count += bad as u64;
                    s += v.as_dvec3();
                }
                out.push(s.to_array());
            }
            progress(tile.pixel_count() as u64 * sample_range.len() as u64);
            (*tile, out, bad_count)
        })
        .collect();
    let mut non_finite = 0;
    for (tile, out, bad) in results {
        non_finite += bad;
        for ((x, y), s) in tile.pixels().zip(out) {
            accum.sum[y as usize * width + x as usize] = s;
        }
    }
    if non_finite > 0 {
        tracing::warn!("{non_finite} reference samples were NaN or infinite and were replaced by zero");
    }
    accum.non_finite_samples += non_finite;
    accum.samples_done = sample_range.end;
    Ok(())
}
