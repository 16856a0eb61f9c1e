//! `cv`: the classic control-variate baseline. The PT means are taken as exact expectations
//! (`V_h = 0`), so the centre must be left out of the set (with it, `β = e_c` would promise
//! zero variance and return plain PT). `β` solves `(V_g + ridge) β = V_fg` from CRN batch
//! covariances. Without `V_h` nothing guards against the PT noise it copies in, and with
//! fewer batches than control variates `V_g` is singular, so the ridge is essential.
use super::finish;
use super::ours::check_selection;
use crate::cv_pass::CvPass;
use crate::input::BatchNeed;
use crate::penalty::Penalty;
use crate::selection::{Selection, Selector};
use crate::solve::MAX_BATCHES;
use crate::{Diagnostics, Estimator, Input, Method, Needs, Output, ReconError};
use std::time::Instant;

#[derive(Clone, Debug, PartialEq)]
pub struct CvOptions {
    pub select: Selection,
    /// Number of control variates, the centre not included.
    pub k: usize,
    pub search_window: usize,
    /// Ridge, relative to the mean diagonal of `V_g`.
    pub ridge: f64,
    pub shared_coefficients: bool,
    /// Seed of `select = random`.
    pub seed: u64,
}

impl Default for CvOptions {
    fn default() -> Self {
        CvOptions { select: Selection::Knn, k: 24, search_window: 11, ridge: 0.3, shared_coefficients: false, seed: 0 }
    }
}

impl CvOptions {
    pub fn validate(&self) -> Result<(), ReconError> {
        // `k` here counts neighbours; on the command line (and in `ours`) it counts the centre too.
        if self.k == 0 {
            return Err(ReconError::option("k", 1, "cv needs at least one neighbour besides the centre: at least 2"));
        }
        check_selection(self.k + 1, self.search_window, self.ridge, "cv-ridge")
    }
}

#[derive(Clone, Debug)]
pub struct Cv {
    options: CvOptions,
}

impl Cv {
    pub fn new(options: CvOptions) -> Result<Self, ReconError> {
        options.validate()?;
        Ok(Cv { options })
    }
}

impl Estimator for Cv {
    fn method(&self) -> Method {
        Method::Cv
    }

    fn needs(&self) -> Needs {
        Needs {
            batches: BatchNeed::Range { min: 2, max: MAX_BATCHES },
            features: (self.options.select == Selection::Gbuffer).then_some("with --select gbuffer"),
            reference: false,
            spp: false,
            bounded_values: true,
        }
    }

    fn settings(&self) -> Vec<(&'static str, String)> {
        let o = &self.options;
        vec![
            ("select", o.select.to_string()),
            ("k", o.k.to_string()),
            ("search_window", o.search_window.to_string()),
            ("ridge", o.ridge.to_string()),
            ("shared_coefficients", o.shared_coefficients.to_string()),
        ]
    }

    fn reconstruct(&self, input: &Input) -> Result<Output, ReconError> {
        let start = Instant::now();
        input.check(self.name(), &self.needs())?;
        let o = &self.options;
        let set = input.streams;
        let pass = CvPass {
            set,
            selector: Selector::new(o.select, o.k, o.search_window, false, o.seed, set),
            k: o.k,
            errors: None,
            penalty: Penalty::None,
            ridge: o.ridge,
            shared: o.shared_coefficients,
            include_centre: false,
            floor: None,
            cross_fit: false,
        };
        let (image, st) = pass.run();
        let mut d = Diagnostics::default();
        st.report(&mut d);
        d.int("batches", set.batch_count() as i64);
        Ok(finish(image, d, start))
    }
}
