//! The canonical serialisation a scene fingerprint hashes: each value's bit pattern,
//! little-endian, arrays with their lengths, so that no formatting of types (a new glam or
//! Rust) can change it.
use glam::Vec3A;

/// The canonical serialisation the fingerprint hashes.
pub(crate) struct Canonical(blake3::Hasher);

impl Canonical {
    pub(crate) fn new() -> Canonical {
        Canonical(blake3::Hasher::new())
    }

    pub(crate) fn finalize(&self) -> blake3::Hash {
        self.0.finalize()
    }

    pub(crate) fn bytes(&mut self, b: &[u8]) {
        self.word(b.len() as u64);
        self.0.update(b);
    }

    pub(crate) fn word(&mut self, w: u64) {
        self.0.update(&w.to_le_bytes());
    }

    pub(crate) fn floats(&mut self, fs: impl IntoIterator<Item = f32>) {
        for f in fs {
            self.0.update(&f.to_bits().to_le_bytes());
        }
    }

    pub(crate) fn vec(&mut self, v: Vec3A) {
        self.floats(v.to_array());
    }

    /// `len` first, so that data cannot move between arrays unnoticed.
    pub(crate) fn array(&mut self, len: usize, items: impl FnOnce(&mut Self)) {
        self.word(len as u64);
        items(self);
    }

    pub(crate) fn texture(&mut self, t: Option<u32>) {
        self.word(t.map_or(0, |i| i as u64 + 1));
    }
}
