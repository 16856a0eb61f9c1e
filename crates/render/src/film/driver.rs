//! The render driver: paired PT/CRN stream renders and progressive PT reference renders,
//! parallel over tiles with rayon and bit-identical for any thread count.
//!
//! For each pixel and each stream, samples `0..spp` are split into `batches` contiguous ranges
//! of `spp / batches` samples (the same ranges in every pixel and both streams); each batch
//! mean and the stream mean are stored. The pixel filter is a box: a sample only counts in the
//! pixel it was taken in.
use crate::error::RenderError;
use crate::film::tiles::{tiles, Tile, TileResult, TileStream, TILE_SIZE};
use crate::intersect::{Hit, Intersector, Ray};
use crate::sampler::{dims, SampleSampler, StreamKind, StreamSampler};
use crate::scene::camera::CameraFrame;
use crate::scene::world::Scene;
use crate::settings::{PathLimits, RenderSettings};
use crate::transport::integrator::{radiance_from_hit, FirstHit, PathContext};
use crate::transport::wavefront::{SceneLanes, Wavefront};
use cvtrace_streams::exact;
use cvtrace_streams::parts::{StreamPart, StreamSums};
use cvtrace_streams::reference::ReferenceAccum;
use cvtrace_streams::{Image, StreamSet};
use glam::{DVec3, Vec3A};
use rayon::prelude::*;
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

/// The memory this driver's renders of these settings take (its tiles, bands and sums), for the
/// check before a render starts.
impl RenderSettings {
    /// About the peak memory in bytes of a stream render of these settings, which goes into
    /// its file band by band ([`crate::film::stream_file`]): per pixel of a band (a row of tiles),
    /// its tile results, images, sums and file channels, measured as for the whole image at
    /// 45–52 bytes per pixel and RGB image plus the sums and, for a part, their 104 planes;
    /// for three bands (one compressing while the next renders, and the compressed blocks).
    pub fn stream_memory_estimate(&self) -> u64 {
        let band = self.width as u64 * TILE_SIZE as u64;
        3 * band * ((2 * (self.batches as u64 + 1) + 2) * 54 + 13 * 16 * 2 + 104 * 4 * 2)
    }

    /// About the peak memory in bytes of a reference render: per pixel the sums, the mean and
    /// the written planes (measured at 63 bytes with f64 sums; the exact sums take 24 more), and
    /// with `checkpoints` (more than one pass) the checkpoint's 27 planes and their copy as well.
    pub fn reference_memory_estimate(&self, checkpoints: bool) -> u64 {
        self.width as u64 * self.height as u64 * if checkpoints { 94 + 27 * 4 * 2 } else { 94 }
    }
}

/// Shared, read-only state of one render.
struct Context<'a, T: Intersector> {
    scene: &'a Scene,
    /// The scene as the wavefronts' lane kernel reads it, if the kernel can shade any of it.
    lanes: Option<SceneLanes>,
    tracer: &'a T,
    frame: CameraFrame,
    limits: PathLimits,
    width: u32,
    /// Vertices the wavefronts shaded, those the lane kernel shaded and those of its glossy
    /// lanes, summed over the tiles and logged when the render ends (the share of the kernel is
    /// what decides how much the wavefront pays on a scene).
    lane_counts: [AtomicU64; 4],
}

impl<T: Intersector> Context<'_, T> {
    /// Adds the vertices a tile's wavefront shaded to the render's counts.
    fn count_vertices(&self, wave: &Wavefront) {
        for (sum, n) in self.lane_counts.iter().zip(wave.vertex_counts()) {
            sum.fetch_add(n, Ordering::Relaxed);
        }
    }
}

impl<T: Intersector> Drop for Context<'_, T> {
    fn drop(&mut self) {
        let [all, kernel, glossy, glass] = self.lane_counts.each_ref().map(|c| c.load(Ordering::Relaxed));
        if all > 0 {
            let share = |n: u64| 100.0 * n as f64 / all as f64;
            tracing::debug!(
                "lane kernel: {:.1}% of {all} vertices ({:.1}% in the glossy lanes, {:.1}% in the glass lanes)",
                share(kernel),
                share(glossy),
                share(glass)
            );
        }
    }
}

/// Camera rays traced together: one sample of neighbouring pixels of a tile (the renders call
/// [`Context::tile_samples`] one sample index at a time, so the groups do not depend on how the
/// samples are split into batches, passes or parts) start in a small footprint and point alike,
/// which Embree's coherent mode traces about 2.5x cheaper per ray (see
/// `Intersector::intersect_coherent`).
const CAMERA_BATCH: usize = 64;

/// Paths followed together (see [`crate::transport::wavefront`]): whole camera batches, so that the
/// camera rays handed to the ray caster at once, and so their coherent batches, stay those
/// of [`CAMERA_BATCH`] consecutive samples.
const WAVE: usize = 4 * CAMERA_BATCH;

/// One wavefront of camera rays, with the tile pixel, sample index and sampler of each.
#[derive(Default)]
struct CameraBatch {
    paths: Vec<(usize, u32, SampleSampler)>,
    rays: Vec<Ray>,
    hits: Vec<Option<Hit>>,
    wave: Wavefront,
}

impl<T: Intersector> Context<'_, T> {
    /// Renders samples `samples` of every pixel of `tile` from `stream`, calling
    /// `each(i, s, value, non_finite, first_hit)` for pixel `i` of the tile (row-major) and
    /// sample `s`, pixel by pixel and in sample order within a pixel, so sums accumulate in a
    /// fixed order. Non-finite values are replaced by zero and flagged. `first_hit` holds the
    /// first-hit features if `features` is set.
    fn tile_samples(
        &self,
        batch: &mut CameraBatch,
        stream: &StreamSampler,
        tile: &Tile,
        samples: Range<u32>,
        features: bool,
        mut each: impl FnMut(usize, u32, Vec3A, bool, &FirstHit),
    ) {
        for (i, (x, y)) in tile.pixels().enumerate() {
            let pixel = y as u64 * self.width as u64 + x as u64;
            for s in samples.clone() {
                let smp = stream.sample(pixel, s);
                batch.rays.push(self.frame.ray(x, y, smp.get2d(dims::PIXEL)));
                batch.paths.push((i, s, smp));
                if batch.rays.len() == WAVE {
                    self.trace_batch(batch, features, &mut each);
                }
            }
        }
        self.trace_batch(batch, features, &mut each);
    }

    /// Traces the batch's camera rays (in coherent groups of [`CAMERA_BATCH`]), then follows
    /// its paths as one wavefront; empties the batch.
    #[inline]
    fn trace_batch(&self, batch: &mut CameraBatch, features: bool, each: &mut impl FnMut(usize, u32, Vec3A, bool, &FirstHit)) {
        batch.hits.clear();
        batch.hits.resize(batch.rays.len(), None);
        self.tracer.intersect_coherent(&batch.rays, &mut batch.hits);
        let mut report = |i, s, v: Vec3A, fh: &FirstHit| {
            let bad = !v.is_finite();
            each(i, s, if bad { Vec3A::ZERO } else { v }, bad, fh);
        };
        match self.lanes.as_ref().filter(|_| batch.wave.pays()) {
            Some(lanes) => {
                batch.wave.clear();
                for ((&(_, _, smp), &ray), &hit) in batch.paths.iter().zip(&batch.rays).zip(&batch.hits) {
                    batch.wave.push(ray, hit, smp);
                }
                batch.wave.run(&PathContext::new(self.scene, self.limits), Some(lanes), self.tracer, features);
                for (k, &(i, s, _)) in batch.paths.iter().enumerate() {
                    report(i, s, batch.wave.radiance(k), batch.wave.first_hit(k));
                }
            }
            // Where the lane kernel shades too few vertices, each path on its own.
            None => {
                for ((&(i, s, smp), &ray), &hit) in batch.paths.iter().zip(&batch.rays).zip(&batch.hits) {
                    let mut fh = FirstHit::default();
                    let first = if features { Some(&mut fh) } else { None };
                    report(i, s, radiance_from_hit(self.scene, self.tracer, self.limits, ray, hit, &smp, first), &fh);
                }
            }
        }
        batch.paths.clear();
        batch.rays.clear();
    }
}

fn context<'a, T: Intersector>(scene: &'a Scene, tracer: &'a T, settings: &RenderSettings) -> Result<Context<'a, T>, RenderError> {
    scene.camera().validate().map_err(RenderError::Camera)?;
    if scene.lights().is_empty() {
        tracing::warn!("the scene has no lights (emissive surfaces, glTF lights or a sidecar environment): the image will be black");
    }
    Ok(Context {
        scene,
        lanes: Some(SceneLanes::new(scene)).filter(SceneLanes::can_shade),
        tracer,
        frame: scene.camera().frame(settings.width, settings.height),
        limits: settings.limits(),
        width: settings.width,
        lane_counts: Default::default(),
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
    let part = render_stream_part(scene, tracer, settings, 0..settings.batches, progress)?;
    Ok(part.into_stream_set(settings.seed, settings.max_depth).expect("a part of every batch is a whole render"))
}

/// Renders batches `batches` (of `settings.batches`) of both streams: their batch means and the
/// exact sums of their samples, which [`StreamPart::append`] joins with the other batches'
/// into exactly what one render of every batch gives.
pub fn render_stream_part<T: Intersector>(
    scene: &Scene,
    tracer: &T,
    settings: &RenderSettings,
    batches: Range<u32>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<StreamPart, RenderError> {
    let render = StreamRender::new(scene, tracer, settings, batches)?;
    // All rows at once: one parallel loop over every tile, with no wait at the end of each band.
    let whole = render.render_band(0..settings.height as usize, progress);
    if whole.non_finite > 0 {
        tracing::warn!("{} samples were NaN or infinite and were replaced by zero", whole.non_finite);
    }
    Ok(whole)
}

/// A stream render of some batches, one band of rows at a time: a band is one row of tiles,
/// full width, and what it gives is final (every sample of its pixels), so a writer can store
/// it and drop it before the next band is rendered.
pub struct StreamRender<'a, T: Intersector> {
    ctx: Context<'a, T>,
    pt: StreamSampler,
    crn: StreamSampler,
    settings: RenderSettings,
    batches: Range<u32>,
}

impl<'a, T: Intersector> StreamRender<'a, T> {
    pub fn new(scene: &'a Scene, tracer: &'a T, settings: &RenderSettings, batches: Range<u32>) -> Result<Self, RenderError> {
        settings.validate()?;
        if batches.is_empty() || batches.end > settings.batches {
            return Err(RenderError::InvalidSettings(format!("batches {batches:?} are not a range of the {} batches", settings.batches)));
        }
        Ok(StreamRender {
            ctx: context(scene, tracer, settings)?,
            pt: StreamSampler::new(settings.seed, StreamKind::Pt),
            crn: StreamSampler::new(settings.seed, StreamKind::Crn),
            settings: settings.clone(),
            batches,
        })
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// The bands' rows, top to bottom: [`TILE_SIZE`] rows each (the last may be fewer).
    pub fn bands(&self) -> impl Iterator<Item = Range<usize>> {
        let (h, t) = (self.settings.height as usize, TILE_SIZE as usize);
        (0..h).step_by(t).map(move |y| y..(y + t).min(h))
    }

    /// Renders rows `rows` (one of [`StreamRender::bands`], or several in a row) in parallel
    /// over their tiles: a part of the rows' height whose pixels are theirs, row-major.
    /// `progress(k)`: `k` more pixel-samples done; every tile also reports `progress(0)` as it
    /// starts, so that a caller that stops the render from its progress (by unwinding: the
    /// Python package on Ctrl-C) waits only for the tiles under way.
    pub fn render_band(&self, rows: Range<usize>, progress: &(dyn Fn(u64) + Sync)) -> StreamPart {
        let settings = &self.settings;
        assert!(rows.start.is_multiple_of(TILE_SIZE as usize), "rows {rows:?} do not start a row of tiles");
        let (w, band_h) = (settings.width as usize, rows.len());
        let y0 = rows.start as u32;
        let band_tiles: Vec<Tile> = (rows.start as u32..rows.end as u32)
            .step_by(TILE_SIZE as usize)
            .flat_map(|ty| {
                let h = TILE_SIZE.min(rows.end as u32 - ty);
                (0..settings.width).step_by(TILE_SIZE as usize).map(move |x0| Tile { x0, y0: ty, w: TILE_SIZE.min(settings.width - x0), h })
            })
            .collect();
        let results: Vec<TileResult> = band_tiles.par_iter().map(|t| self.render_tile(t, progress)).collect();
        let nb = self.batches.len();
        let blank = || Image::new(w, band_h);
        let mut pt_batches: Vec<Image> = (0..nb).map(|_| blank()).collect();
        let mut crn_batches: Vec<Image> = (0..nb).map(|_| blank()).collect();
        let mut sums = StreamSums::zero(w * band_h);
        let mut non_finite = 0u64;
        for r in &results {
            non_finite += r.non_finite;
            for (i, (x, y)) in r.tile.pixels().enumerate() {
                let p = (y - y0) as usize * w + x as usize;
                sums.pt[p] = r.pt.sum[i];
                sums.crn[p] = r.crn.sum[i];
                for b in 0..nb {
                    pt_batches[b].pixels[p] = r.pt.batches[b][i];
                    crn_batches[b].pixels[p] = r.crn.batches[b][i];
                }
                sums.albedo[p] = r.albedo[i];
                sums.normal[p] = r.normal[i];
                sums.depth[p] = r.depth[i];
            }
        }
        StreamPart {
            width: w,
            height: band_h,
            spp: settings.spp,
            batches: settings.batches,
            range: self.batches.clone(),
            pt: pt_batches,
            crn: crn_batches,
            sums,
            non_finite,
        }
    }

    fn render_tile(&self, tile: &Tile, progress: &(dyn Fn(u64) + Sync)) -> TileResult {
        progress(0);
        let (ctx, pt, crn) = (&self.ctx, &self.pt, &self.crn);
        let nb = self.batches.len();
        let per_batch = self.settings.spp / self.settings.batches;
        let samples = self.batches.start * per_batch..self.batches.end * per_batch;
        let batch_of = |s: u32| ((s - samples.start) / per_batch) as usize;
        let n = tile.pixel_count();
        let mut r = TileResult {
            tile: *tile,
            pt: TileStream::new(n, nb),
            crn: TileStream::new(n, nb),
            albedo: vec![[0; 3]; n],
            normal: vec![[0; 3]; n],
            depth: vec![0; n],
            non_finite: 0,
        };
        // Sample by sample over the tile's pixels, so that the camera rays traced together (and
        // so Embree's coherent traversal of them) are the same whichever batches or passes a
        // render covers: a part draws exactly the one-shot render's samples.
        let mut batch = vec![DVec3::ZERO; n];
        let close_batch = |batch: &mut Vec<DVec3>| -> Vec<[f32; 3]> {
            batch.iter_mut().map(|b| (std::mem::take(b) / per_batch as f64).as_vec3().to_array()).collect()
        };
        let mut camera = CameraBatch::default();
        // PT with features.
        r.pt.sum = vec![[0; 3]; n];
        for s in samples.clone() {
            ctx.tile_samples(&mut camera, pt, tile, s..s + 1, true, |i, _, v, bad, fh| {
                r.non_finite += bad as u64;
                exact::add3(&mut r.pt.sum[i], exact::fixed3(v.to_array()));
                batch[i] += v.as_dvec3();
                exact::add3(&mut r.albedo[i], exact::fixed3(fh.albedo.to_array()));
                exact::add3(&mut r.normal[i], exact::fixed3(fh.normal.to_array()));
                r.depth[i] += exact::fixed(fh.depth);
            });
            if (s + 1) % per_batch == 0 {
                r.pt.batches[batch_of(s)] = close_batch(&mut batch);
            }
        }
        // Each stream's samples as they are done: the progress moves (and a caller may stop)
        // halfway through a tile too.
        progress(n as u64 * samples.len() as u64);
        // CRN.
        r.crn.sum = vec![[0; 3]; n];
        for s in samples.clone() {
            ctx.tile_samples(&mut camera, crn, tile, s..s + 1, false, |i, _, v, bad, _| {
                r.non_finite += bad as u64;
                exact::add3(&mut r.crn.sum[i], exact::fixed3(v.to_array()));
                batch[i] += v.as_dvec3();
            });
            if (s + 1) % per_batch == 0 {
                r.crn.batches[batch_of(s)] = close_batch(&mut batch);
            }
        }
        progress(n as u64 * samples.len() as u64);
        ctx.count_vertices(&camera.wave);
        r
    }
}

/// Adds PT samples `sample_range` of every pixel to `accum` (the range must start at
/// `accum.first + accum.samples_done`). Sample `s` uses the same random numbers as sample `s` of the PT
/// stream in [`render_streams`]. `progress(k)`: `k` more pixel-samples done, and `progress(0)`
/// as each tile starts (see [`StreamRender::render_band`]).
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
    if sample_range.start != accum.first + accum.samples_done {
        return mismatch(format!(
            "pass starts at sample {} but samples {}..{} are done",
            sample_range.start,
            accum.first,
            accum.first + accum.samples_done
        ));
    }
    if sample_range.end <= sample_range.start {
        return Err(RenderError::InvalidSettings(format!("empty sample range {sample_range:?}")));
    }
    let ctx = context(scene, tracer, settings)?;
    let pt = StreamSampler::new(settings.seed, StreamKind::Pt);
    let width = settings.width as usize;
    let sums = &accum.sum;
    let results: Vec<(Tile, Vec<[i128; 3]>, u64)> = tiles(settings.width, settings.height)
        .par_iter()
        .map(|tile| {
            progress(0);
            let mut out: Vec<[i128; 3]> = tile.pixels().map(|(x, y)| sums[y as usize * width + x as usize]).collect();
            let mut bad_count = 0u64;
            let mut camera = CameraBatch::default();
            // Sample by sample, as the streams: the same rays are traced together whatever the passes.
            for s in sample_range.clone() {
                ctx.tile_samples(&mut camera, &pt, tile, s..s + 1, false, |i, _, v, bad, _| {
                    bad_count += bad as u64;
                    exact::add3(&mut out[i], exact::fixed3(v.to_array()));
                });
            }
            progress(tile.pixel_count() as u64 * sample_range.len() as u64);
            ctx.count_vertices(&camera.wave);
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
    accum.samples_done = sample_range.end - accum.first;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::tiles::PixelSums;
    use crate::testing::{cornell_box, BruteForce};
    use crate::transport::integrator::radiance;

    /// Every stored value must be what rendering each sample on its own gives, bit for bit:
    /// camera rays go in batches that cross pixel and tile boundaries (20×12 pixels in 16-pixel
    /// tiles, 6 samples per pixel, 64 rays per batch), and sums must still follow sample order.
    #[test]
    fn batched_camera_rays_give_the_per_sample_results() {
        let scene = cornell_box();
        let tracer = BruteForce::new(&scene);
        let settings = RenderSettings { width: 20, height: 12, spp: 6, batches: 3, seed: 5, max_depth: 6, rr_depth: 3 };
        let frame = scene.camera().frame(settings.width, settings.height);
        let limits = settings.limits();
        let one = |stream: &StreamSampler, x: u32, y: u32, s: u32, fh: Option<&mut FirstHit>| {
            let smp = stream.sample(y as u64 * settings.width as u64 + x as u64, s);
            radiance(&scene, &tracer, limits, frame.ray(x, y, smp.get2d(dims::PIXEL)), &smp, fh)
        };
        let set = render_streams(&scene, &tracer, &settings, &|_| {}).unwrap();
        let features = set.features.as_ref().unwrap();
        let mut reference = ReferenceAccum::new(&settings.reference());
        render_reference_pass(&scene, &tracer, &settings, &mut reference, 0..4, &|_| {}).unwrap();
        reference.samples_done = 4;
        render_reference_pass(&scene, &tracer, &settings, &mut reference, 4..9, &|_| {}).unwrap();
        let (pt, crn) = (StreamSampler::new(5, StreamKind::Pt), StreamSampler::new(5, StreamKind::Crn));
        for y in 0..settings.height {
            for x in 0..settings.width {
                let p = (y * settings.width + x) as usize;
                let (mut sums, mut crn_sums, mut albedo) = (PixelSums::default(), PixelSums::default(), [0i128; 3]);
                for s in 0..settings.spp {
                    let mut fh = FirstHit::default();
                    sums.add(one(&pt, x, y, s, Some(&mut fh)));
                    exact::add3(&mut albedo, exact::fixed3(fh.albedo.to_array()));
                    crn_sums.add(one(&crn, x, y, s, None));
                    if (s + 1) % 2 == 0 {
                        let b = (s / 2) as usize;
                        assert_eq!(set.pt.batches[b].pixels[p], sums.take_batch_mean(2), "PT batch {b} of pixel ({x}, {y})");
                        assert_eq!(set.crn.batches[b].pixels[p], crn_sums.take_batch_mean(2), "CRN batch {b} of pixel ({x}, {y})");
                    }
                }
                assert_eq!(set.pt.mean.pixels[p], exact::mean3(sums.total, 6), "PT mean of ({x}, {y})");
                assert_eq!(set.crn.mean.pixels[p], exact::mean3(crn_sums.total, 6), "CRN mean of ({x}, {y})");
                assert_eq!(features.albedo.pixels[p], exact::mean3(albedo, 6), "albedo of ({x}, {y})");
                let mut sum = [0i128; 3];
                for s in 0..9 {
                    exact::add3(&mut sum, exact::fixed3(one(&pt, x, y, s, None).to_array()));
                }
                assert_eq!(reference.sum[p], sum, "reference sum of ({x}, {y})");
            }
        }
    }
}
