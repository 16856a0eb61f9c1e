//! Colours of methods in plots and the viewer. Each method brings its own (the estimator's
//! spec declares it and `results.json` carries it); methods without one get a fallback from a
//! palette chosen to read well on the viewer's dark background, by position.
use crate::results::SceneResult;

const FALLBACK: [[u8; 3]; 6] =
    [[0xff, 0x9d, 0xa7], [0x86, 0xbc, 0xb6], [0xd4, 0xa6, 0xc8], [0x9d, 0x75, 0x5f], [0xf1, 0xce, 0x63], [0x79, 0x70, 0x6e]];

/// The colour of method `key` in `scene`: its own, or the fallback for position `index`.
pub fn method_colour(scene: &SceneResult, key: &str, index: usize) -> [u8; 3] {
    scene.method(key).and_then(|m| m.colour.as_deref()).and_then(parse_hex).unwrap_or(FALLBACK[index % FALLBACK.len()])
}

/// `#rrggbb`.
pub fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// `#rrggbb` (either case) as bytes.
pub fn parse_hex(s: &str) -> Option<[u8; 3]> {
    let digits = s.strip_prefix('#')?;
    if digits.len() != 6 || !digits.is_ascii() {
        return None;
    }
    let byte = |i: usize| u8::from_str_radix(&digits[i..i + 2], 16).ok();
    Some([byte(0)?, byte(2)?, byte(4)?])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trips_and_bad_text_is_no_colour() {
        assert_eq!(hex([0, 0x0a, 0xff]), "#000aff");
        assert_eq!(parse_hex("#000AFF"), Some([0, 0x0a, 0xff]));
        for bad in ["000aff", "#00af", "#00afgg", "#ééé"] {
            assert_eq!(parse_hex(bad), None, "{bad}");
        }
    }
}
