//! `render --part I/N`, and why a part could not be made or the parts not merged.
use crate::error::{StreamError, SumsError};
use std::ops::Range;

/// Why a part could not be made or the parts not merged. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum PartError {
    #[error("--part {0}")]
    Spec(String),
    #[error(transparent)]
    File(#[from] StreamError),
    #[error(transparent)]
    Sums(#[from] SumsError),
    #[error("{0}")]
    Parts(String),
}

/// `--part I/N`: part `I` (0-based) of `N`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartSpec {
    pub index: u32,
    pub count: u32,
}

impl std::str::FromStr for PartSpec {
    type Err = String;
    fn from_str(s: &str) -> Result<PartSpec, String> {
        let usage = || format!("{s:?}: expected I/N, part I (counted from 0) of N parts, e.g. 3/8");
        let (i, n) = s.split_once('/').ok_or_else(usage)?;
        let (index, count): (u32, u32) = (i.trim().parse().map_err(|_| usage())?, n.trim().parse().map_err(|_| usage())?);
        if count == 0 {
            return Err(format!("{s}: there must be at least one part"));
        }
        if index >= count {
            return Err(format!("{s}: parts are numbered 0 to {} of {count}", count - 1));
        }
        Ok(PartSpec { index, count })
    }
}

impl std::fmt::Display for PartSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl PartSpec {
    /// The units (batches or passes) of part `index` of `count` over `units`: contiguous,
    /// sizes differing by at most one, every unit in exactly one part. More parts than units
    /// would leave some empty, which is refused.
    pub fn range(&self, units: u32, what: &str) -> Result<Range<u32>, PartError> {
        if self.count > units {
            return Err(PartError::Spec(format!("{self}: {} parts but only {units} {what}; a part is at least one of them", self.count)));
        }
        let at = |i: u32| (i as u64 * units as u64 / self.count as u64) as u32;
        Ok(at(self.index)..at(self.index + 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn part_specs_split_every_unit_once() {
        let spec = |s: &str| s.parse::<PartSpec>();
        assert_eq!(spec("3/8").unwrap().range(16, "batches").unwrap(), 6..8);
        let ranges: Vec<_> = (0..3).map(|i| PartSpec { index: i, count: 3 }.range(7, "batches").unwrap()).collect();
        assert_eq!(ranges, [0..2, 2..4, 4..7]);
        for bad in ["9/8", "8/8", "0/0", "x/2", "1", "-1/2"] {
            assert!(spec(bad).is_err(), "{bad}");
        }
        let e = spec("2/9").unwrap().range(8, "batches").unwrap_err().to_string();
        assert!(e.contains("9 parts but only 8 batches"), "{e}");
    }
}
