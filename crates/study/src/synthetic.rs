//! A source without a renderer: the analytic soft-shadow scene of
//! `cvtrace_reconstruct::synthetic`, rendered in memory.
use crate::{Rendered, Source, SourceError};
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_streams::Image;
use std::time::Instant;

pub struct SyntheticSource {
    pub scene: SoftShadowScene,
    pub width: usize,
    pub height: usize,
}

impl SyntheticSource {
    pub fn new(width: usize, height: usize) -> Self {
        SyntheticSource { scene: SoftShadowScene::default(), width, height }
    }

    /// The exact image, the reference of every study on this source.
    pub fn reference(&self) -> Image {
        self.scene.reference(self.width, self.height)
    }

    fn spec(&self, spp: u32, batches: u32, seed: u64) -> RenderSpec {
        RenderSpec { width: self.width, height: self.height, spp, batches: batches as usize, seed }
    }
}

impl Source for SyntheticSource {
    fn streams(&mut self, n: u32, batches: u32, seed: u64) -> Result<Rendered<cvtrace_streams::StreamSet>, SourceError> {
        let t = Instant::now();
        let value = self.scene.render(&self.spec(n, batches, seed))?;
        Ok(Rendered { value, seconds: t.elapsed().as_secs_f64(), name: format!("synthetic streams, seed {seed}") })
    }

    fn pt(&mut self, spp: u32, seed: u64) -> Result<Rendered<Image>, SourceError> {
        let t = Instant::now();
        // One batch: the image is the mean of all its samples.
        let value = self.scene.render_pt(&self.spec(spp, 1, seed), 0)?.mean;
        Ok(Rendered { value, seconds: t.elapsed().as_secs_f64(), name: format!("synthetic PT, seed {seed}") })
    }
}
