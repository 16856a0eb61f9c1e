//! What the scene-loading tests share.

/// A unit quad in z = 0 (two triangles): 4 positions then 6 u16 indices, 60 bytes.
pub fn quad_buffer() -> Vec<u8> {
    let mut b = Vec::new();
    for p in [[0f32, 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]] {
        for c in p {
            b.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b
}
