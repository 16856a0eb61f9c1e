//! Header attributes as cvtrace writes and reads them, shared by the whole-file reader and
//! writer (`exr_io`) and the block-by-block writer (`block_writer`).

/// A header attribute value. Integers that fit are stored as EXR `int`, the rest as `string`.
#[derive(Clone, Debug, PartialEq)]
pub enum AttrValue {
    Int(i32),
    Float(f32),
    Text(String),
}

impl AttrValue {
    pub fn as_text(&self) -> String {
        match self {
            AttrValue::Int(v) => v.to_string(),
            AttrValue::Float(v) => v.to_string(),
            AttrValue::Text(s) => s.clone(),
        }
    }
}
