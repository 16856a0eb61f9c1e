//! The symmetric penalty of `ours`: a heuristic on the PT error estimates `V_h`.
//!
//! The supplement reports that it helps when the errors come from a filter (−15% relMSE)
//! and costs a little with oracle errors (+5%); its exact form is not public, so the variants
//! here are our candidates (see docs/estimators.md for what we measured).
use crate::named::named_enum;

named_enum! {
    /// How neighbour `i`'s PT error estimate `e_i` is made symmetric in (centre `c`, `i`).
    pub enum Penalty: "penalty" {
        /// `e_i` as estimated.
        None => "none",
        /// `(e_i + e_c) / 2`: a neighbour is never trusted much more than the centre.
        Avg => "avg",
        /// `max(e_i, e_c)`.
        Max => "max",
        /// `e_i + ((h̄_i − h̄_c) − (ḡ_i − ḡ_c))²`: adds the observed disagreement of the pair.
        Residual => "residual",
    }
}

impl Penalty {
    /// The error used for a neighbour (never for the centre itself, which keeps `e_c`).
    /// `residual` is `(h̄_i − h̄_c) − (ḡ_i − ḡ_c)`.
    #[inline]
    pub fn apply(self, e_i: f64, e_c: f64, residual: f64) -> f64 {
        match self {
            Penalty::None => e_i,
            Penalty::Avg => 0.5 * (e_i + e_c),
            Penalty::Max => e_i.max(e_c),
            Penalty::Residual => e_i + residual * residual,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_by_hand() {
        assert_eq!(Penalty::None.apply(1.0, 3.0, 2.0), 1.0);
        assert_eq!(Penalty::Avg.apply(1.0, 3.0, 2.0), 2.0);
        assert_eq!(Penalty::Max.apply(1.0, 3.0, 2.0), 3.0);
        assert_eq!(Penalty::Residual.apply(1.0, 3.0, 2.0), 5.0);
        assert_eq!("AVG".parse::<Penalty>().unwrap(), Penalty::Avg);
        assert!("sym".parse::<Penalty>().unwrap_err().to_string().contains("none, avg, max, residual"));
    }
}
