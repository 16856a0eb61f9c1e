//! Method names and the factory that turns a name plus options into an estimator.
use crate::estimators::{Average, Crn, Cv, CvOptions, Iduw, IduwOptions, Ours, OursOptions, Pt};
use crate::named::named_enum;
use crate::{Estimator, ParseNameError, ReconError};
use std::fmt;
use std::str::FromStr;

named_enum! {
    /// A reconstruction method.
    pub enum Method: "method" {
        /// The PT stream mean alone.
        Pt => "pt",
        /// The CRN stream mean alone.
        Crn => "crn",
        /// The mean of all samples of both streams.
        Average => "average",
        /// Input-dependent uncorrelated weighting (Back et al. 2023).
        Iduw => "iduw",
        /// Classic control variates with the PT means taken as exact expectations.
        Cv => "cv",
        /// Imperfect image-space control variates (Yang & Moon 2025).
        Ours => "ours",
    }
}

/// A `--method` argument: one method, or `all` of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MethodChoice {
    One(Method),
    All,
}

impl MethodChoice {
    /// Every accepted name: the methods, then `all`.
    pub const NAMES: &'static [&'static str] = &["pt", "crn", "average", "iduw", "cv", "ours", "all"];

    pub fn methods(self) -> Vec<Method> {
        match self {
            MethodChoice::One(m) => vec![m],
            MethodChoice::All => Method::ALL.to_vec(),
        }
    }
}

impl fmt::Display for MethodChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MethodChoice::One(m) => m.fmt(f),
            MethodChoice::All => f.write_str("all"),
        }
    }
}

impl FromStr for MethodChoice {
    type Err = ParseNameError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        if s.trim().eq_ignore_ascii_case("all") {
            return Ok(MethodChoice::All);
        }
        s.parse::<Method>().map(MethodChoice::One).map_err(|e| ParseNameError { expected: MethodChoice::NAMES, ..e })
    }
}

/// The options of every configurable method; `Default` is the measured default set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Options {
    pub ours: OursOptions,
    pub iduw: IduwOptions,
    pub cv: CvOptions,
}

/// Builds an estimator, rejecting absurd options before any data is read.
pub fn build(method: Method, options: &Options) -> Result<Box<dyn Estimator>, ReconError> {
    Ok(match method {
        Method::Pt => Box::new(Pt),
        Method::Crn => Box::new(Crn),
        Method::Average => Box::new(Average),
        Method::Iduw => Box::new(Iduw::new(options.iduw.clone())?),
        Method::Cv => Box::new(Cv::new(options.cv.clone())?),
        Method::Ours => Box::new(Ours::new(options.ours.clone())?),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_choices() {
        for m in Method::ALL {
            assert_eq!(m.to_string().parse::<Method>().unwrap(), *m);
            assert_eq!(m.to_string().parse::<MethodChoice>().unwrap(), MethodChoice::One(*m));
        }
        assert_eq!("ALL".parse::<MethodChoice>().unwrap().methods().len(), 6);
        let e = "bilateral".parse::<MethodChoice>().unwrap_err().to_string();
        assert!(e.contains("bilateral") && e.contains("ours") && e.contains("all"), "{e}");
    }

    #[test]
    fn factory_builds_every_method_with_defaults() {
        for m in Method::ALL {
            let e = build(*m, &Options::default()).unwrap();
            assert_eq!(e.method(), *m);
            assert_eq!(e.name(), m.name());
        }
    }
}
