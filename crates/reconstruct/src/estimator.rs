//! The trait an estimator file implements, and what it returns. [`crate::Instance`] is the
//! framework around it.
use crate::{Diagnostics, Input, ReconError};
use cvtrace_streams::Image;

/// The reconstructed image and what the method reports about it.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    pub image: Image,
    pub diagnostics: Diagnostics,
    /// Further per-pixel layers (AOVs), written as `<name>.R/G/B`; `ours` gives `variance`,
    /// its predicted variance per pixel.
    pub aovs: Vec<(String, Image)>,
}

impl Output {
    /// An image without diagnostics.
    pub fn image(image: Image) -> Self {
        Output::new(image, Diagnostics::default())
    }

    /// An image with its diagnostics and no further layers.
    pub fn new(image: Image, diagnostics: Diagnostics) -> Self {
        Output { image, diagnostics, aovs: Vec::new() }
    }

    /// The layer called `name`, if the estimator gave one.
    pub fn aov(&self, name: &str) -> Option<&Image> {
        self.aovs.iter().find(|(n, _)| n == name).map(|(_, im)| im)
    }
}

/// The reconstruction proper. Called through [`crate::Instance::run`], the input has been checked
/// against the spec's `needs` (sizes, batch counts, finite and bounded values, features,
/// reference, spp); called directly, the caller vouches for it.
pub trait Estimator: Send + Sync {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError>;
}
