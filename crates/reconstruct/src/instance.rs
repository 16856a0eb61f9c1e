//! [`Instance`], the framework around an [`Estimator`]: an estimator built from its spec and
//! parameters, whose `run` checks the input against the declared needs, times the call and
//! records the settings, so that no estimator repeats that.
use crate::estimator::{Estimator, Output};
use crate::spec::{EstimatorSpec, Params};
use crate::{Input, Needs, ReconError};
use std::time::Instant;

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
