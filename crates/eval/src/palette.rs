//! One colour per method, shared by the convergence plots and the viewer so a method
//! looks the same everywhere. Chosen to read well on the viewer's dark background.
use crate::results::keys;

const EXTRA: [[u8; 3]; 6] = [
    [0xff, 0x9d, 0xa7],
    [0x86, 0xbc, 0xb6],
    [0xd4, 0xa6, 0xc8],
    [0x9d, 0x75, 0x5f],
    [0xf1, 0xce, 0x63],
    [0x79, 0x70, 0x6e],
];

/// The colour of method `key`; `index` picks a stable fallback colour for other names.
pub fn method_color(key: &str, index: usize) -> [u8; 3] {
    match key {
        keys::PT => [0xe1, 0x57, 0x59],
        keys::CRN => [0xf2, 0x8e, 0x2b],
        keys::AVERAGE => [0xed, 0xc9, 0x48],
        keys::IDUW => [0x76, 0xb7, 0xf2],
        keys::CV => [0xb0, 0x7a, 0xe1],
        keys::OURS => [0x59, 0xd9, 0x8e],
        keys::PT_2N => [0xc8, 0xc0, 0xbc],
        _ => EXTRA[index % EXTRA.len()],
    }
}

/// `#rrggbb`.
pub fn hex(c: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_methods_have_distinct_colours() {
        let cs: Vec<_> = keys::ORDER.iter().map(|k| method_color(k, 0)).collect();
        for i in 0..cs.len() {
            for j in 0..i {
                assert_ne!(cs[i], cs[j], "{} and {}", keys::ORDER[i], keys::ORDER[j]);
            }
        }
        assert_eq!(hex([0, 0x0a, 0xff]), "#000aff");
    }
}
