//! The exact sums of a progressive PT reference render, or of one part of it. A checkpoint
//! ([`crate::checkpoint`]) saves them between passes, a reference part ([`crate::parts`])
//! holds those of its passes, and the finished reference is their mean.
use crate::error::SumsError;
use crate::exact;
use crate::image::Image;

/// What a reference's sums belong to: the image size, the seed and path limits that decide
/// every sample, and the samples per pixel the reference is to reach.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReferenceSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub seed: u64,
    pub max_depth: i32,
    pub rr_depth: u32,
}

/// Running sums of a progressive PT reference render, or of one part of it: samples
/// `first..first + samples_done` of every pixel. The sums are exact ([`crate::exact`]), so N
/// samples give bit-identical results however the render is split into passes or parts, and
/// equal the PT stream mean of a stream render at the same seed.
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceAccum {
    pub width: u32,
    pub height: u32,
    pub sum: Vec<[i128; 3]>,
    /// The first sample index in the sums (0 but for a part).
    pub first: u32,
    pub samples_done: u32,
    pub seed: u64,
    pub max_depth: i32,
    pub rr_depth: u32,
    pub non_finite_samples: u64,
}

impl ReferenceAccum {
    /// An empty accumulator for `settings` (its resolution, seed and path limits).
    pub fn new(settings: &ReferenceSettings) -> ReferenceAccum {
        ReferenceAccum {
            width: settings.width,
            height: settings.height,
            sum: vec![[0; 3]; settings.width as usize * settings.height as usize],
            first: 0,
            samples_done: 0,
            seed: settings.seed,
            max_depth: settings.max_depth,
            rr_depth: settings.rr_depth,
            non_finite_samples: 0,
        }
    }

    /// Resumes from a saved mean image of `samples_done` samples. The sums are rebuilt from f32
    /// means, so a resumed reference matches an uninterrupted one only to f32 rounding.
    pub fn from_mean(settings: &ReferenceSettings, mean: &Image, samples_done: u32) -> Result<ReferenceAccum, SumsError> {
        if mean.width != settings.width as usize || mean.height != settings.height as usize {
            return Err(SumsError::Reference(format!(
                "saved reference is {}x{}, the render is {}x{}",
                mean.width, mean.height, settings.width, settings.height
            )));
        }
        let mut acc = ReferenceAccum::new(settings);
        let n = samples_done as f64;
        for (s, m) in acc.sum.iter_mut().zip(&mean.pixels) {
            *s = m.map(|v| exact::fixed_f64(v as f64 * n));
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
        let n = self.samples_done as u64;
        Image { width: w, height: h, pixels: self.sum.iter().map(|s| exact::mean3(*s, n)).collect() }
    }

    /// Adds the samples of `next`, which must be the same render's and start where these end.
    pub fn append(&mut self, next: &ReferenceAccum) -> Result<(), SumsError> {
        let end = self.first + self.samples_done;
        if (next.width, next.height, next.seed, next.max_depth, next.rr_depth)
            != (self.width, self.height, self.seed, self.max_depth, self.rr_depth)
        {
            return Err(SumsError::Reference("the sums are of different renders".into()));
        }
        if next.first != end {
            return Err(SumsError::Reference(format!("samples from {} follow samples ending at {end}", next.first)));
        }
        for (a, b) in self.sum.iter_mut().zip(&next.sum) {
            exact::add3(a, *b);
        }
        self.samples_done += next.samples_done;
        self.non_finite_samples += next.non_finite_samples;
        Ok(())
    }
}
