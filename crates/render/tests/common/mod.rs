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

/// The glTF `buffers`, `bufferViews` and `accessors` of [`quad_buffer`] stored at `buffer_uri`
/// (accessor 0: positions, 1: indices), for the end of a glTF object.
pub fn quad_buffer_json(buffer_uri: &str) -> String {
    format!(
        r#""buffers": [{{"byteLength": 60, "uri": "{buffer_uri}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}
  ]"#
    )
}
