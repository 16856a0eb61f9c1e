//! The trait an estimator file implements, and [`Instance`], the framework around it: an
//! estimator built from its spec and parameters, whose `run` checks the input against the
//! declared needs, times the call and records the settings, so that no estimator repeats that.
use crate::spec::{EstimatorSpec, Params};
use crate::{Diagnostics, Input, Needs, ReconError};
use cvtrace_streams::Image;
use std::time::Instant;

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

/// The reconstruction proper. Called through [`Instance::run`], the input has been checked
/// against the spec's `needs` (sizes, batch counts, finite and bounded values, features,
/// reference, spp); called directly, the caller vouches for it.
pub trait Estimator: Send + Sync {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError>;
}

/// An estimator with the spec and parameters it was built from.
pub struct Instance {
    spec: &'static EstimatorSpec,
    params: Params,
    needs: Needs,
    estimator: Box<dyn Estimator>,
}

impl std::fmt::Debug for Instance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Instance").field("name", &self.spec.name).field("params", &self.params.settings()).finish_non_exhaustive()
    }
}

impl Instance {
    /// Builds the estimator `params` are for.
    pub fn new(params: Params) -> Result<Self, ReconError> {
        let spec = params.spec();
        let needs = (spec.needs)(&params);
        let estimator = (spec.build)(&params)?;
        Ok(Instance { spec, params, needs, estimator })
    }

    pub fn spec(&self) -> &'static EstimatorSpec {
        self.spec
    }

    /// The command-line name (`ours`, `iduw`, ...).
    pub fn name(&self) -> &'static str {
        self.spec.name
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    /// What the input must provide.
    pub fn needs(&self) -> Needs {
        self.needs
    }

    /// Every parameter in effect, as (name, value): what each output records.
    pub fn settings(&self) -> Vec<(&'static str, String)> {
        self.params.settings()
    }

    /// Checks the input, reconstructs, and sets the diagnostics' wall-clock time (input check
    /// included).
    pub fn run(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        input.check(self.spec.name, &self.needs)?;
        let mut out = self.estimator.reconstruct(input)?;
        out.diagnostics.seconds = start.elapsed().as_secs_f64();
        Ok(out)
    }
}

/// An instance is an estimator too: its `reconstruct` is [`Instance::run`], checks and timing
/// included, so configured estimators compose with code written for the trait.
impl Estimator for Instance {
    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        self.run(input)
    }
}
