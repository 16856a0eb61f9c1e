//! What an estimator reports besides its image: an ordered list of named values
//! (e.g. IDUW's chosen γ, the mean centre weight of `ours`) plus wall-clock time,
//! ready to print, to store as EXR header attributes or to write as JSON.
use std::fmt;

#[derive(Clone, Debug, PartialEq)]
pub enum DiagValue {
    Float(f64),
    Int(i64),
    Text(String),
}

impl fmt::Display for DiagValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DiagValue::Float(v) => write!(f, "{v}"),
            DiagValue::Int(v) => write!(f, "{v}"),
            DiagValue::Text(v) => f.write_str(v),
        }
    }
}

impl DiagValue {
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            DiagValue::Float(v) => Some(*v),
            DiagValue::Int(v) => Some(*v as f64),
            DiagValue::Text(_) => None,
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Diagnostics {
    /// Named values in the order the estimator produced them.
    pub entries: Vec<(&'static str, DiagValue)>,
    /// Wall-clock seconds of `reconstruct`, validation included.
    pub seconds: f64,
}

impl Diagnostics {
    pub fn float(&mut self, name: &'static str, v: f64) -> &mut Self {
        self.entries.push((name, DiagValue::Float(v)));
        self
    }

    pub fn int(&mut self, name: &'static str, v: i64) -> &mut Self {
        self.entries.push((name, DiagValue::Int(v)));
        self
    }

    pub fn text(&mut self, name: &'static str, v: impl Into<String>) -> &mut Self {
        self.entries.push((name, DiagValue::Text(v.into())));
        self
    }

    /// The first value of that name.
    pub fn get(&self, name: &str) -> Option<&DiagValue> {
        self.entries.iter().find(|(n, _)| *n == name).map(|(_, v)| v)
    }

    /// A flat JSON object (`seconds` included); non-finite floats become `null`.
    pub fn to_json(&self) -> String {
        let mut s = String::from("{");
        for (name, v) in &self.entries {
            s.push_str(&format!("{}: ", json_string(name)));
            match v {
                DiagValue::Float(x) if x.is_finite() => s.push_str(&format!("{x}")),
                DiagValue::Float(_) => s.push_str("null"),
                DiagValue::Int(x) => s.push_str(&x.to_string()),
                DiagValue::Text(t) => s.push_str(&json_string(t)),
            }
            s.push_str(", ");
        }
        s.push_str(&format!("\"seconds\": {}}}", if self.seconds.is_finite() { self.seconds } else { 0.0 }));
        s
    }
}

impl fmt::Display for Diagnostics {
    /// One `name = value` per line, then the time.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (name, v) in &self.entries {
            writeln!(f, "{name} = {v}")?;
        }
        write!(f, "seconds = {:.3}", self.seconds)
    }
}

fn json_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for ch in s.chars() {
        match ch {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_and_display_keep_order_and_escape() {
        let mut d = Diagnostics::default();
        d.float("gamma", 0.5).int("pixels", 4).text("note", "a \"b\"");
        d.seconds = 1.25;
        assert_eq!(d.to_json(), r#"{"gamma": 0.5, "pixels": 4, "note": "a \"b\"", "seconds": 1.25}"#);
        assert_eq!(d.to_string(), "gamma = 0.5\npixels = 4\nnote = a \"b\"\nseconds = 1.250");
        assert_eq!(d.get("pixels").and_then(DiagValue::as_f64), Some(4.0));
    }
}
