//! Diagnostics over seeds: numbers averaged, text kept from the first seed.
use cvtrace_reconstruct::{DiagValue, Diagnostics};

#[derive(Default)]
pub(crate) struct DiagnosticsMean {
    entries: Vec<(String, Option<f64>, DiagValue)>,
    seeds: usize,
}

impl DiagnosticsMean {
    pub(crate) fn add(&mut self, d: &Diagnostics) {
        for (name, v) in &d.entries {
            match self.entries.iter_mut().find(|(n, _, _)| n == name) {
                Some((_, sum, _)) => *sum = sum.zip(v.as_f64()).map(|(s, x)| s + x),
                None => self.entries.push((name.to_string(), v.as_f64(), v.clone())),
            }
        }
        self.seeds += 1;
    }

    pub(crate) fn finish(&self) -> Vec<(String, serde_json::Value)> {
        let n = self.seeds.max(1) as f64;
        self.entries
            .iter()
            .map(|(name, sum, first)| {
                let v = match sum {
                    Some(s) => serde_json::Number::from_f64(s / n).map(serde_json::Value::Number).unwrap_or(serde_json::Value::Null),
                    None => serde_json::Value::String(first.to_string()),
                };
                (name.clone(), v)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_averaged_and_text_kept_from_the_first_seed() {
        let mut m = DiagnosticsMean::default();
        for (g, note) in [(1.0, "a"), (2.0, "b")] {
            let mut d = Diagnostics::default();
            d.float("gamma", g).int("pixels", 4).text("note", note);
            m.add(&d);
        }
        let out = m.finish();
        assert_eq!(out[0], ("gamma".to_string(), serde_json::json!(1.5)));
        assert_eq!(out[1], ("pixels".to_string(), serde_json::json!(4.0)));
        assert_eq!(out[2], ("note".to_string(), serde_json::json!("a")));
    }
}
