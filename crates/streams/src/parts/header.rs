//! What a part's header records: its kind and range, the whole render's provenance, the scene
//! and the count of replaced samples, and the check that it is a complete record of a part.
use crate::error::StreamError;
use crate::exr_io::{AttrValue, ExrChannels};
use crate::provenance::{Field, Provenance};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The attribute that makes a file a part, and its two layouts.
pub const KIND_ATTR: &str = "cvtrace.part";
pub const STREAMS_KIND: &str = "streams-v1";
pub const REFERENCE_KIND: &str = "reference-v1";
/// The part's range: batches of a stream render, sample indices of a reference (EXR `int`s).
pub const ATTR_FIRST: &str = "cvtrace.partFirst";
pub const ATTR_END: &str = "cvtrace.partEnd";
/// `I/N` as given to `render --part`, for messages.
pub const ATTR_OF: &str = "cvtrace.partOf";
pub(crate) const ATTR_SCENE: &str = "cvtrace.scene";
pub(crate) const ATTR_NON_FINITE: &str = "cvtrace.nonFiniteSamples";

/// What a part's header says: its kind, range, the render's record and scene.
#[derive(Clone, Debug)]
pub struct PartHeader {
    pub path: PathBuf,
    pub kind: String,
    pub range: Range<u32>,
    pub provenance: Provenance,
    pub scene: String,
    pub non_finite: u64,
}

impl PartHeader {
    /// "batches 4..6" or "samples 0..512".
    pub fn describe_range(&self) -> String {
        format!("{} {}..{}", self.unit(), self.range.start, self.range.end)
    }

    pub(crate) fn unit(&self) -> &'static str {
        if self.kind == STREAMS_KIND {
            "batches"
        } else {
            "samples"
        }
    }

    /// How many units the whole render has (batches, or samples of a reference).
    pub(crate) fn total(&self) -> u32 {
        let p = &self.provenance;
        if self.kind == STREAMS_KIND {
            p.batches.unwrap_or(0)
        } else {
            p.spp.unwrap_or(0)
        }
    }

    /// Reads the header of the part at `path`, checking it is a complete record of a part.
    pub fn read(path: &Path) -> Result<PartHeader, StreamError> {
        let invalid = |m: String| StreamError::invalid(path, m);
        let (w, h, attrs) = ExrChannels::read_header(path)?;
        let kind = match attrs.get(KIND_ATTR).map(AttrValue::as_text) {
            Some(k) if k == STREAMS_KIND || k == REFERENCE_KIND => k,
            Some(k) => return Err(invalid(format!("a part of layout {k:?}, which this cvtrace does not know"))),
            None => return Err(invalid("not a part of a render (no cvtrace.part attribute): give the files `render --part` wrote".into())),
        };
        let int = |k: &str| match attrs.get(k) {
            Some(AttrValue::Int(v)) if *v >= 0 => Ok(*v as u32),
            _ => Err(invalid(format!("part lacks a valid {k}"))),
        };
        let range = int(ATTR_FIRST)?..int(ATTR_END)?;
        let provenance = Provenance::from_attributes(w, h, &attrs, path)?;
        let mut required = vec![Field::Seed, Field::MaxDepth, Field::RrDepth, Field::SceneHash, Field::Camera, Field::Spp];
        if kind == STREAMS_KIND {
            required.push(Field::Batches);
        }
        provenance.require(&required, path, "part")?;
        if provenance.version.is_none() {
            return Err(invalid("part lacks the attribute cvtrace.version".into()));
        }
        let scene = attrs.get(ATTR_SCENE).map(AttrValue::as_text).unwrap_or_default();
        let non_finite = attrs.get(ATTR_NON_FINITE).map(AttrValue::as_text).unwrap_or_default();
        let non_finite = non_finite.parse().map_err(|_| invalid(format!("part lacks a valid {ATTR_NON_FINITE}")))?;
        let header = PartHeader { path: path.to_path_buf(), kind, range, provenance, scene, non_finite };
        if header.range.is_empty() || header.range.end > header.total() {
            return Err(invalid(format!(
                "{} is not a range of the render's {} {}",
                header.describe_range(),
                header.total(),
                header.unit()
            )));
        }
        if header.kind == STREAMS_KIND && !header.provenance.spp.unwrap_or(0).is_multiple_of(header.total()) {
            return Err(invalid("part's cvtrace.spp is not a multiple of its cvtrace.batches".into()));
        }
        Ok(header)
    }
}
