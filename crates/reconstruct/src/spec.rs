//! What an estimator declares about itself: one [`EstimatorSpec`] per estimator file, with its
//! name and label, what it reads, how many samples its output stands for, its parameters with
//! defaults, ranges and docs, and its constructor.
//!
//! The framework reads everything else from the spec: the command line's `--param
//! method.name=value` and flag aliases, `--list` and `--help-method`, the parameter tables of
//! docs/estimators.md, the settings recorded in every output (all parameters, always), the
//! labels and colours in `results.json`, and which inputs a study must render.
use crate::{Estimator, Needs, ReconError};
use std::fmt;

/// A declared estimator. Built-in ones live in [`crate::estimators`]; another crate declares a
/// `static` of its own and adds it to a [`crate::Registry`].
pub struct EstimatorSpec {
    /// Command-line name and result key: lower case, digits and `-` (e.g. `ours`).
    pub name: &'static str,
    /// Display label in tables and the viewer (e.g. `CV (baseline)`).
    pub label: &'static str,
    /// Short label for ratio names and narrow headers (e.g. `CV`).
    pub short: &'static str,
    /// One line: what the estimator is.
    pub summary: &'static str,
    /// Colour in plots and the viewer (sRGB), chosen to read on a dark background.
    pub colour: [u8; 3],
    /// How many samples per pixel the output stands for.
    pub samples: Samples,
    /// The parameters, in the order they are listed and recorded.
    pub params: &'static [ParamSpec],
    /// What the input must hold with these parameters (checked before `reconstruct`).
    pub needs: fn(&Params) -> Needs,
    /// Makes the estimator; the parameters are already parsed and within their declared ranges.
    pub build: fn(&Params) -> Result<Box<dyn Estimator>, ReconError>,
    /// Named variants a study runs with `--ablations` (the estimator with some parameters set).
    pub variants: &'static [Variant],
}

impl fmt::Debug for EstimatorSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("EstimatorSpec").field("name", &self.name).finish_non_exhaustive()
    }
}

impl EstimatorSpec {
    /// The declared parameter `name` (`-` and `_` are the same).
    pub fn param(&self, name: &str) -> Option<(usize, &'static ParamSpec)> {
        let wanted = name.trim().replace('-', "_");
        self.params.iter().enumerate().find(|(_, p)| p.name == wanted)
    }

    /// The parameter names, for error messages.
    pub fn param_names(&self) -> String {
        if self.params.is_empty() {
            "none".into()
        } else {
            self.params.iter().map(|p| p.name).collect::<Vec<_>>().join(", ")
        }
    }

    /// The spec as `--help-method` prints it: summary, samples, needs and parameters.
    pub fn help(&'static self) -> String {
        let needs = (self.needs)(&Params::defaults(self));
        let mut s = format!("{} — {}\n{}\n\n", self.name, self.label, self.summary);
        s += &format!("output: {}\n", self.samples.describe());
        s += &format!("reads (defaults): {}\n", needs.describe());
        if self.params.is_empty() {
            s += "parameters: none\n";
        } else {
            s += "parameters (--param NAME.PARAM=VALUE):\n";
            for p in self.params {
                let alias = p.alias.map(|a| format!(", flag --{a}")).unwrap_or_default();
                s += &format!("  {}.{} = {}  [{}{alias}]\n      {}\n", self.name, p.name, p.default, p.kind, p.doc);
            }
        }
        s
    }
}

impl EstimatorSpec {
    /// The parameter table of docs/estimators.md, between its markers.
    pub fn markdown(&self) -> String {
        let mut s = format!("<!-- parameters of {}: generated from its spec; a test fails when they differ -->\n", self.name);
        if self.params.is_empty() {
            s += &format!("`{}` has no parameters.\n", self.name);
        } else {
            s += "| parameter | default | type, range | flag | meaning |\n|---|---|---|---|---|\n";
            for p in self.params {
                let flag = p.alias.map(|a| format!("`--{a}`")).unwrap_or_default();
                s += &format!("| `{}.{}` | `{}` | {} | {flag} | {} |\n", self.name, p.name, p.default, p.kind, p.doc.replace('|', "\\|"));
            }
        }
        s += &format!("<!-- end of the parameters of {} -->\n", self.name);
        s
    }
}

/// How many samples per pixel an estimator's output uses, in units of one stream's `n`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Samples {
    /// One stream (`n` spp): PT or CRN alone.
    OneStream,
    /// Both streams (`2n` spp).
    BothStreams,
    /// The PT(2n) image ([`crate::Input::pt2n`]): `2n` spp of another render, none of the
    /// streams' (their features aside).
    Pt2n,
}

impl Samples {
    /// Total samples per pixel for streams of `n` spp each.
    pub fn total(self, n: u32) -> u32 {
        match self {
            Samples::OneStream => n,
            Samples::BothStreams | Samples::Pt2n => 2 * n,
        }
    }

    /// The share of a stream-pair render an output's samples cost (none for the PT(2n) image,
    /// a render of its own).
    pub fn render_share(self) -> f64 {
        match self {
            Samples::OneStream => 0.5,
            Samples::BothStreams => 1.0,
            Samples::Pt2n => 0.0,
        }
    }

    /// `n` or `2n`, as results and docs write it.
    pub fn describe(self) -> &'static str {
        match self {
            Samples::OneStream => "n spp (one stream)",
            Samples::BothStreams => "2n spp (both streams)",
            Samples::Pt2n => "2n spp (a PT(2n) render)",
        }
    }
}

/// One variant of an estimator for a study's ablations.
#[derive(Clone, Copy, Debug)]
pub struct Variant {
    /// Result key, e.g. `ours-no-penalty`.
    pub key: &'static str,
    pub label: &'static str,
    /// Parameters set on top of the study's own, as (name, value) text.
    pub params: &'static [(&'static str, &'static str)],
}

/// A declared parameter.
#[derive(Clone, Copy, Debug)]
pub struct ParamSpec {
    /// `snake_case`; on the command line `-` may stand for `_`.
    pub name: &'static str,
    pub kind: ParamKind,
    /// The default, as it would be written on the command line.
    pub default: &'static str,
    pub doc: &'static str,
    /// A plain command-line flag that sets this parameter (one flag may set the parameter of
    /// several estimators, as `--k` does for `ours` and `cv`).
    pub alias: Option<&'static str>,
}

/// The type and range of a parameter.
#[derive(Clone, Copy, Debug)]
pub enum ParamKind {
    /// An integer in `min..=max`.
    Int { min: i64, max: i64 },
    /// A finite number within the bounds.
    Float(Bounds),
    /// `true` or `false` (an alias flag without a value sets `true`).
    Bool,
    /// One of the names.
    Choice(&'static [&'static str]),
    /// A comma-separated, non-empty list of numbers within the bounds.
    FloatList(Bounds),
    /// `auto`, or a number within the bounds.
    AutoFloat(Bounds),
}

/// Bounds of a number: at least (or above) `min`, at most `max`.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub min: f64,
    /// `min` itself is excluded.
    pub above: bool,
    pub max: f64,
}

impl Bounds {
    pub const fn at_least(min: f64) -> Self {
        Bounds { min, above: false, max: f64::INFINITY }
    }

    pub const fn positive() -> Self {
        Bounds { min: 0.0, above: true, max: f64::INFINITY }
    }

    pub const fn between(min: f64, max: f64) -> Self {
        Bounds { min, above: false, max }
    }

    fn contains(&self, v: f64) -> bool {
        v.is_finite() && (if self.above { v > self.min } else { v >= self.min }) && v <= self.max
    }

    fn describe(&self) -> String {
        let low = if self.above { format!("> {}", self.min) } else { format!("≥ {}", self.min) };
        if self.max.is_finite() {
            format!("finite, {low} and ≤ {}", self.max)
        } else {
            format!("finite, {low}")
        }
    }
}

impl fmt::Display for ParamKind {
    /// The type and range, as `--help-method` and the docs' tables show them.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamKind::Int { min, max } => write!(f, "integer {min}..{max}"),
            ParamKind::Float(b) => write!(f, "number, {}", b.describe().trim_start_matches("finite, ")),
            ParamKind::Bool => f.write_str("true/false"),
            ParamKind::Choice(names) => f.write_str(&names.join("/")),
            ParamKind::FloatList(b) => write!(f, "list of numbers, each {}", b.describe().trim_start_matches("finite, ")),
            ParamKind::AutoFloat(b) => write!(f, "auto or a number, {}", b.describe().trim_start_matches("finite, ")),
        }
    }
}

/// A parsed parameter value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    Int(i64),
    Float(f64),
    Bool(bool),
    Choice(&'static str),
    FloatList(Vec<f64>),
    /// `AutoFloat` set to `auto`.
    Auto,
}

impl fmt::Display for Value {
    /// The canonical text, which parses back to the same value.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Int(v) => write!(f, "{v}"),
            Value::Float(v) => write!(f, "{v}"),
            Value::Bool(v) => write!(f, "{v}"),
            Value::Choice(v) => f.write_str(v),
            Value::FloatList(vs) => f.write_str(&vs.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",")),
            Value::Auto => f.write_str("auto"),
        }
    }
}

impl ParamKind {
    /// Parses and range-checks `text`; the error says what is allowed.
    pub fn parse(&self, text: &str) -> Result<Value, String> {
        let t = text.trim();
        let number = |b: &Bounds, s: &str| -> Result<f64, String> {
            let v: f64 = s.trim().parse().map_err(|_| format!("`{s}` is not a number"))?;
            if b.contains(v) {
                Ok(v)
            } else {
                Err(format!("must be {}", b.describe()))
            }
        };
        match self {
            ParamKind::Int { min, max } => {
                let v: i64 = t.parse().map_err(|_| format!("`{t}` is not an integer"))?;
                if v < *min || v > *max {
                    return Err(format!("must be between {min} and {max}"));
                }
                Ok(Value::Int(v))
            }
            ParamKind::Float(b) => number(b, t).map(Value::Float),
            ParamKind::Bool => match t.to_ascii_lowercase().as_str() {
                "true" | "1" | "yes" | "on" => Ok(Value::Bool(true)),
                "false" | "0" | "no" | "off" => Ok(Value::Bool(false)),
                _ => Err("must be true or false".into()),
            },
            ParamKind::Choice(names) => names
                .iter()
                .find(|n| n.eq_ignore_ascii_case(t))
                .map(|n| Value::Choice(n))
                .ok_or_else(|| format!("expected one of: {}", names.join(", "))),
            ParamKind::FloatList(b) => {
                if t.is_empty() {
                    return Err("give at least one number".into());
                }
                t.split(',').map(|s| number(b, s)).collect::<Result<Vec<_>, _>>().map(Value::FloatList)
            }
            ParamKind::AutoFloat(b) => {
                if t.eq_ignore_ascii_case("auto") {
                    Ok(Value::Auto)
                } else {
                    number(b, t).map(Value::Float)
                }
            }
        }
    }
}

/// The values of every parameter of one estimator: its defaults with the given ones applied.
#[derive(Clone, Debug)]
pub struct Params {
    spec: &'static EstimatorSpec,
    values: Vec<Value>,
}

impl PartialEq for Params {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.spec, other.spec) && self.values == other.values
    }
}

impl Params {
    /// The declared defaults. A default that does not parse is a bug in the spec, which the
    /// registry's tests catch for every registered estimator.
    pub fn defaults(spec: &'static EstimatorSpec) -> Self {
        let values = spec
            .params
            .iter()
            .map(|p| p.kind.parse(p.default).unwrap_or_else(|e| panic!("{}.{}: default `{}`: {e}", spec.name, p.name, p.default)))
            .collect();
        Params { spec, values }
    }

    pub fn spec(&self) -> &'static EstimatorSpec {
        self.spec
    }

    /// Sets parameter `name` from its text; unknown names and bad values are errors that name
    /// the estimator, the parameter and what it accepts.
    pub fn set(&mut self, name: &str, text: &str) -> Result<&mut Self, ReconError> {
        let spec = self.spec;
        let (i, p) = spec.param(name).ok_or_else(|| ReconError::UnknownParam {
            method: spec.name.to_string(),
            param: name.to_string(),
            known: spec.param_names(),
        })?;
        self.values[i] = p.kind.parse(text).map_err(|why| ReconError::InvalidParam {
            method: spec.name,
            param: p.name,
            alias: p.alias,
            value: text.trim().to_string(),
            why,
        })?;
        Ok(self)
    }

    /// `(name, value)` of every parameter in declared order: the settings an output records.
    pub fn settings(&self) -> Vec<(&'static str, String)> {
        self.spec.params.iter().zip(&self.values).map(|(p, v)| (p.name, v.to_string())).collect()
    }

    /// The value of a declared parameter. Asking for an undeclared name is a bug in the
    /// estimator's file, not bad input: it panics, and the registry's tests build every
    /// estimator with its defaults.
    pub fn get(&self, name: &str) -> &Value {
        match self.spec.param(name) {
            Some((i, _)) => &self.values[i],
            None => panic!("{} declares no parameter `{name}`", self.spec.name),
        }
    }

    fn wrong(&self, name: &str, wanted: &str) -> ! {
        panic!("{}.{name} is declared as {:?}, read as {wanted}", self.spec.name, self.get(name))
    }

    pub fn int(&self, name: &str) -> i64 {
        match self.get(name) {
            Value::Int(v) => *v,
            _ => self.wrong(name, "an integer"),
        }
    }

    /// An integer parameter whose declared range is non-negative.
    pub fn usize(&self, name: &str) -> usize {
        usize::try_from(self.int(name)).unwrap_or_else(|_| self.wrong(name, "a non-negative integer"))
    }

    pub fn float(&self, name: &str) -> f64 {
        match self.get(name) {
            Value::Float(v) => *v,
            _ => self.wrong(name, "a number"),
        }
    }

    pub fn bool(&self, name: &str) -> bool {
        match self.get(name) {
            Value::Bool(v) => *v,
            _ => self.wrong(name, "true/false"),
        }
    }

    /// A `Choice` parameter as the enum whose names it declares.
    pub fn choice<T: std::str::FromStr>(&self, name: &str) -> T {
        match self.get(name) {
            Value::Choice(v) => v.parse().unwrap_or_else(|_| self.wrong(name, "a declared name")),
            _ => self.wrong(name, "a choice"),
        }
    }

    pub fn float_list(&self, name: &str) -> &[f64] {
        match self.get(name) {
            Value::FloatList(v) => v,
            _ => self.wrong(name, "a list of numbers"),
        }
    }

    /// An `AutoFloat` parameter: `None` for `auto`.
    pub fn auto_float(&self, name: &str) -> Option<f64> {
        match self.get(name) {
            Value::Auto => None,
            Value::Float(v) => Some(*v),
            _ => self.wrong(name, "auto or a number"),
        }
    }
}

impl Needs {
    /// What an estimator reads, in words, for `--list` and `--help-method`.
    pub fn describe(&self) -> String {
        use crate::BatchNeed;
        let mut parts = vec!["stream means".to_string()];
        match self.batches {
            BatchNeed::None => {}
            BatchNeed::Range { min, max } => parts.push(format!("{min}–{max} batches")),
            BatchNeed::MultipleOf(m) => parts.push(format!("a multiple of {m} batches")),
        }
        if self.features.is_some() {
            parts.push("features".into());
        }
        if self.reference {
            parts.push("a reference".into());
        }
        if self.spp {
            parts.push("spp".into());
        }
        if self.pt2n {
            parts.push("a PT(2n) image".into());
        }
        parts.join(", ")
    }
}
