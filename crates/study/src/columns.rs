//! The columns of a study: every registered estimator, the study's own PT(2n) image, and with
//! ablations every variant the estimators declare, each with the study's parameters plus its own.
use crate::StudyError;
use cvtrace_eval::results::{keys, MethodResult};
use cvtrace_eval::stats::SeedStats;
use cvtrace_reconstruct::{EstimatorSpec, Instance, Overrides, Registry, Samples};

/// Colour of the study's own PT(2n) image.
pub const PT_2N_COLOUR: [u8; 3] = [0xc8, 0xc0, 0xbc];

/// One column: its key, labels and colour, how many samples it stands for, how its image is
/// made, and for an ablation the key of the estimator it varies.
pub struct Column {
    pub key: String,
    pub label: String,
    pub short: String,
    pub colour: [u8; 3],
    pub samples: Samples,
    pub kind: ColumnKind,
    pub base: Option<String>,
}

pub enum ColumnKind {
    /// An estimator on the stream set.
    Estimator(Instance),
    /// The real PT image with `2n` spp.
    Pt2n,
}

impl Column {
    fn of(key: &str, label: &str, spec: &'static EstimatorSpec, instance: Instance, base: Option<String>) -> Column {
        Column {
            key: key.into(),
            label: label.into(),
            short: spec.short.into(),
            colour: spec.colour,
            samples: spec.samples,
            kind: ColumnKind::Estimator(instance),
            base,
        }
    }

    /// The column's result from its seed statistics with `n` spp per stream; times, images
    /// and diagnostics are the caller's.
    pub fn result(&self, stats: &SeedStats, n: u32) -> MethodResult {
        let mut m = MethodResult::from_stats(&self.key, &self.label, self.samples.total(n), stats);
        m.ablation = self.base.is_some();
        m.base = self.base.clone();
        m.short = self.short.clone();
        m.colour = Some(cvtrace_eval::palette::hex(self.colour));
        if let ColumnKind::Estimator(est) = &self.kind {
            m.settings = est.settings().into_iter().map(|(k, v)| (k.to_string(), v)).collect();
        }
        m
    }
}

/// Every estimator of `registry` with `overrides`, the PT(2n) image, then (with `ablations`)
/// every declared variant.
pub fn columns(registry: &Registry, overrides: &Overrides, ablations: bool) -> Result<Vec<Column>, StudyError> {
    let mut list = Vec::new();
    for spec in registry.specs() {
        list.push(Column::of(spec.name, spec.label, spec, registry.build(spec.name, overrides)?, None));
    }
    list.push(Column {
        key: keys::PT_2N.into(),
        label: "PT (2n)".into(),
        short: "PT(2n)".into(),
        colour: PT_2N_COLOUR,
        samples: Samples::BothStreams,
        kind: ColumnKind::Pt2n,
        base: None,
    });
    if ablations {
        for spec in registry.specs() {
            for v in spec.variants {
                let instance = registry.build(spec.name, &overrides.with(spec.name, v.params))?;
                list.push(Column::of(v.key, v.label, spec, instance, Some(spec.name.into())));
            }
        }
    }
    Ok(list)
}

/// Headline ratios given as `NUMERATOR/DENOMINATOR` keys, each a column of the study.
pub fn headline(ratios: &[String], columns: &[Column]) -> Result<Vec<(String, String)>, StudyError> {
    ratios
        .iter()
        .map(|r| {
            let (a, b) = r
                .split_once('/')
                .ok_or_else(|| StudyError::Invalid(format!("--headline {r}: give NUMERATOR/DENOMINATOR, e.g. ours/iduw")))?;
            for k in [a, b] {
                if !columns.iter().any(|c| c.key == k) {
                    let keys: Vec<&str> = columns.iter().map(|c| c.key.as_str()).collect();
                    return Err(StudyError::Invalid(format!(
                        "--headline {r}: `{k}` is not a column of this study; its columns: {}",
                        keys.join(", ")
                    )));
                }
            }
            Ok((a.to_string(), b.to_string()))
        })
        .collect()
}
