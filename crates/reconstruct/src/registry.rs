//! The estimators a program knows, by name, and the parameter assignments a user gives them.
//!
//! ```
//! use cvtrace_reconstruct::{Overrides, Registry};
//! let registry = Registry::builtin();
//! let mut overrides = Overrides::default();
//! overrides.parse_assignment("ours.k=16").unwrap();
//! let ours = registry.build("ours", &overrides).unwrap();
//! assert!(ours.settings().contains(&("k", "16".to_string())));
//! assert!(registry.build("ours", &Overrides::parse(["ours.kk=3"]).unwrap()).is_err());
//! ```
use crate::spec::{EstimatorSpec, Params};
use crate::{estimators, Instance, ReconError};

/// Names a registered estimator may not take: `all` selects every one, and `pt2n` is the study's
/// real PT render with `2n` spp.
pub const RESERVED_NAMES: [&str; 2] = ["all", "pt2n"];

/// Estimators by name, in registration order (the order of tables and the viewer).
#[derive(Clone, Debug, Default)]
pub struct Registry {
    specs: Vec<&'static EstimatorSpec>,
}

impl Registry {
    /// An empty registry.
    pub fn new() -> Self {
        Registry::default()
    }

    /// The built-in estimators: pt, crn, average, iduw, cv, ours.
    pub fn builtin() -> Self {
        let mut r = Registry::new();
        for spec in estimators::BUILTIN {
            r.register(spec).expect("the built-in estimators have distinct valid names");
        }
        r
    }

    /// Adds an estimator. Its name must be new, not reserved, and made of lower-case letters,
    /// digits and `-`; so must its variants' keys.
    pub fn register(&mut self, spec: &'static EstimatorSpec) -> Result<&mut Self, ReconError> {
        let keys = std::iter::once(spec.name).chain(spec.variants.iter().map(|v| v.key));
        for key in keys {
            let valid = !key.is_empty()
                && key.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
                && !RESERVED_NAMES.contains(&key);
            if !valid {
                return Err(ReconError::BadSpec {
                    method: spec.name.to_string(),
                    why: format!("`{key}` is not a usable name: lower-case letters, digits and `-`, not {}", RESERVED_NAMES.join(" or ")),
                });
            }
            if self.specs.iter().any(|s| s.name == key || s.variants.iter().any(|v| v.key == key)) {
                return Err(ReconError::BadSpec { method: spec.name.to_string(), why: format!("`{key}` is registered already") });
            }
        }
        for p in spec.params {
            if spec.params.iter().filter(|q| q.name == p.name).count() > 1 || p.name.contains('-') {
                return Err(ReconError::BadSpec {
                    method: spec.name.to_string(),
                    why: format!("parameter `{}` is declared twice or has a `-` (use `_`)", p.name),
                });
            }
            if let Err(e) = p.kind.parse(p.default) {
                return Err(ReconError::BadSpec {
                    method: spec.name.to_string(),
                    why: format!("the default of `{}`, `{}`: {e}", p.name, p.default),
                });
            }
        }
        self.specs.push(spec);
        Ok(self)
    }

    /// Every registered spec, in order.
    pub fn specs(&self) -> &[&'static EstimatorSpec] {
        &self.specs
    }

    /// The spec called `name` (case-insensitive). The key of a variant is no estimator: its
    /// error says whose variant it is and how to run it.
    pub fn get(&self, name: &str) -> Result<&'static EstimatorSpec, ReconError> {
        let wanted = name.trim();
        if let Some(spec) = self.specs.iter().copied().find(|s| s.name.eq_ignore_ascii_case(wanted)) {
            return Ok(spec);
        }
        for spec in &self.specs {
            if let Some(v) = spec.variants.iter().find(|v| v.key.eq_ignore_ascii_case(wanted)) {
                let params = v.params.iter().map(|(p, value)| format!("--param {}.{p}={value}", spec.name)).collect::<Vec<_>>().join(" ");
                return Err(ReconError::Variant { given: v.key.to_string(), method: spec.name, params });
            }
        }
        Err(ReconError::UnknownMethod { given: name.to_string(), known: self.names_and_all() })
    }

    fn names_and_all(&self) -> String {
        self.specs.iter().map(|s| s.name).chain(["all"]).collect::<Vec<_>>().join(", ")
    }

    /// `all`, or a comma-separated list of names, as specs (each once, in the order given).
    pub fn select(&self, text: &str) -> Result<Vec<&'static EstimatorSpec>, ReconError> {
        if text.trim().eq_ignore_ascii_case("all") {
            return Ok(self.specs.clone());
        }
        let mut out: Vec<&'static EstimatorSpec> = Vec::new();
        for name in text.split(',') {
            let spec = self.get(name)?;
            if !out.iter().any(|s| std::ptr::eq(*s, spec)) {
                out.push(spec);
            }
        }
        Ok(out)
    }

    /// The parameters of `spec` with every assignment for it applied.
    pub fn params(&self, spec: &'static EstimatorSpec, overrides: &Overrides) -> Result<Params, ReconError> {
        let mut p = Params::defaults(spec);
        for (method, name, value) in &overrides.entries {
            if method.eq_ignore_ascii_case(spec.name) {
                p.set(name, value)?;
            }
        }
        Ok(p)
    }

    /// Builds estimator `name` with its assignments from `overrides`.
    pub fn build(&self, name: &str, overrides: &Overrides) -> Result<Instance, ReconError> {
        let spec = self.get(name)?;
        Instance::new(self.params(spec, overrides)?)
    }

    /// Checks every assignment: each names a registered estimator and one of its parameters,
    /// with a valid value, and every estimator so configured builds (its own checks across
    /// parameters included). An option of a method that is not run is as much a mistake.
    pub fn check(&self, overrides: &Overrides) -> Result<(), ReconError> {
        for (method, _, _) in &overrides.entries {
            self.get(method)?;
        }
        for spec in &self.specs {
            if overrides.entries.iter().any(|(m, _, _)| m.eq_ignore_ascii_case(spec.name)) {
                Instance::new(self.params(spec, overrides)?)?;
            }
        }
        Ok(())
    }
}

/// Parameter assignments `method.param=value`, applied in order (a later one wins).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Overrides {
    entries: Vec<(String, String, String)>,
}

impl Overrides {
    /// Assignments from `method.param=value` texts.
    pub fn parse<I: IntoIterator<Item = S>, S: AsRef<str>>(assignments: I) -> Result<Self, ReconError> {
        let mut o = Overrides::default();
        for a in assignments {
            o.parse_assignment(a.as_ref())?;
        }
        Ok(o)
    }

    /// Adds one `method.param=value`.
    pub fn parse_assignment(&mut self, text: &str) -> Result<&mut Self, ReconError> {
        let bad = || ReconError::BadAssignment { given: text.to_string() };
        let (lhs, value) = text.split_once('=').ok_or_else(bad)?;
        let (method, param) = lhs.split_once('.').ok_or_else(bad)?;
        if method.trim().is_empty() || param.trim().is_empty() {
            return Err(bad());
        }
        Ok(self.set(method.trim(), param.trim(), value.trim()))
    }

    /// Adds one assignment.
    pub fn set(&mut self, method: &str, param: &str, value: &str) -> &mut Self {
        self.entries.push((method.to_string(), param.to_string(), value.to_string()));
        self
    }

    /// The same assignments followed by `(param, value)` pairs for `method`.
    pub fn with(&self, method: &str, params: &[(&str, &str)]) -> Self {
        let mut o = self.clone();
        for (p, v) in params {
            o.set(method, p, v);
        }
        o
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// Builds a built-in estimator with `method.param=value` assignments: the short way for
/// programs that need no estimators of their own.
pub fn build(name: &str, overrides: &Overrides) -> Result<Instance, ReconError> {
    Registry::builtin().build(name, overrides)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::ParamKind;

    #[test]
    fn every_builtin_builds_with_its_defaults_and_records_every_parameter() {
        let r = Registry::builtin();
        let names: Vec<_> = r.specs().iter().map(|s| s.name).collect();
        assert_eq!(names, ["pt", "crn", "average", "iduw", "cv", "ours"]);
        for spec in r.specs() {
            let e = r.build(spec.name, &Overrides::default()).unwrap();
            assert_eq!(e.name(), spec.name);
            let recorded: Vec<_> = e.settings().into_iter().map(|(k, _)| k).collect();
            let declared: Vec<_> = spec.params.iter().map(|p| p.name).collect();
            assert_eq!(recorded, declared, "{}", spec.name);
            // `study --ablations` builds every variant over the defaults.
            for v in spec.variants {
                let o = Overrides::default().with(spec.name, v.params);
                if let Err(e) = r.build(spec.name, &o) {
                    panic!("variant {} of {}: {e}", v.key, spec.name);
                }
            }
        }
    }

    #[test]
    fn unknown_methods_parameters_and_values_are_named() {
        let r = Registry::builtin();
        let e = r.get("bilateral").unwrap_err().to_string();
        assert!(e.contains("bilateral") && e.contains("ours") && e.contains("all"), "{e}");
        let e = r.build("ours", &Overrides::parse(["ours.kk=3"]).unwrap()).unwrap_err().to_string();
        assert!(e.contains("kk") && e.contains("search_window"), "{e}");
        let e = r.build("ours", &Overrides::parse(["ours.k=0"]).unwrap()).unwrap_err().to_string();
        assert!(e.contains("ours.k") && e.contains("--k") && e.contains("between 1 and"), "{e}");
        let e = r.check(&Overrides::parse(["neural.k=3"]).unwrap()).unwrap_err().to_string();
        assert!(e.contains("neural"), "{e}");
        // A variant's key says whose variant it is and how to run it.
        let e = r.get("cv-classic").unwrap_err().to_string();
        assert!(e.contains("variant of `cv`") && e.contains("study --ablations") && e.contains("--param cv.pt_noise=false"), "{e}");
        assert!(Overrides::parse(["ours.k"]).is_err() && Overrides::parse(["k=3"]).is_err());
        // Hyphens stand for underscores; a later assignment wins.
        let o = Overrides::parse(["ours.search-window=7", "ours.search_window=9"]).unwrap();
        assert!(r.build("ours", &o).unwrap().settings().contains(&("search_window", "9".into())));
        assert_eq!(r.select("OURS,pt,ours").unwrap().iter().map(|s| s.name).collect::<Vec<_>>(), ["ours", "pt"]);
        assert_eq!(r.select("all").unwrap().len(), r.specs().len());
    }

    #[test]
    fn every_declared_range_is_enforced_at_its_ends() {
        let r = Registry::builtin();
        for spec in r.specs() {
            for p in spec.params {
                let (ok, bad): (Vec<String>, Vec<String>) = match p.kind {
                    ParamKind::Int { min, max } => {
                        (vec![min.to_string(), max.to_string()], vec![(min as i128 - 1).to_string(), (max as i128 + 1).to_string()])
                    }
                    ParamKind::Float(b) | ParamKind::AutoFloat(b) | ParamKind::FloatList(b) => {
                        let mut bad = vec!["nan".to_string(), "inf".to_string()];
                        if b.above || b.min.is_finite() {
                            bad.push(if b.above { b.min.to_string() } else { (b.min - 1.0).to_string() });
                        }
                        (vec![], bad)
                    }
                    ParamKind::Bool => (vec!["true".into(), "false".into()], vec!["maybe".into()]),
                    ParamKind::Choice(names) => (names.iter().map(|n| n.to_string()).collect(), vec!["nonsense".into()]),
                };
                for v in bad {
                    let o = Overrides::default().with(spec.name, &[(p.name, &v)]);
                    assert!(r.params(spec, &o).is_err(), "{}.{} = {v} accepted", spec.name, p.name);
                }
                for v in ok {
                    let o = Overrides::default().with(spec.name, &[(p.name, &v)]);
                    assert!(r.params(spec, &o).is_ok(), "{}.{} = {v} refused", spec.name, p.name);
                }
            }
        }
    }

    #[test]
    fn registering_twice_or_a_reserved_name_is_refused() {
        let mut r = Registry::builtin();
        assert!(r.register(&crate::estimators::pt::SPEC).unwrap_err().to_string().contains("registered already"));
        static ALL: EstimatorSpec = EstimatorSpec {
            name: "all",
            label: "All",
            short: "all",
            summary: "a name that --method all would shadow",
            colour: [0, 0, 0],
            samples: crate::Samples::OneStream,
            params: &[],
            needs: |_| crate::Needs::MEANS,
            build: |_| Ok(Box::new(crate::estimators::Pt)),
            variants: &[],
        };
        assert!(r.register(&ALL).unwrap_err().to_string().contains("not a usable name"));
    }
}
