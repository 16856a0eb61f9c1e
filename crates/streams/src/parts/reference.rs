//! The part of a reference render (the exact sums of a range of its passes) and the finished
//! reference that parts add up to.
use super::header::{PartHeader, ATTR_END, ATTR_FIRST, ATTR_NON_FINITE, ATTR_OF, ATTR_SCENE, KIND_ATTR, REFERENCE_KIND};
use super::spec::PartSpec;
use crate::error::StreamError;
use crate::exact::{insert_sums3, take_sums3};
use crate::exr_io::{put_rgb, write_rgb, AttrValue, ExrChannels};
use crate::provenance::Provenance;
use crate::reference::ReferenceAccum;
use std::path::Path;

/// Writes the finished reference of `accum` (samples `0..accum.samples_done`): what a
/// one-shot reference and a merge both write. `provenance` gets the sample count.
pub fn write_reference(
    path: &Path,
    accum: &ReferenceAccum,
    provenance: &Provenance,
    scene: &str,
    overwrite: bool,
) -> Result<(), StreamError> {
    let provenance = Provenance { spp: Some(accum.samples_done), batches: None, ..provenance.clone() };
    let mut attributes = provenance.attributes();
    attributes
        .extend([(ATTR_SCENE, AttrValue::Text(scene.into())), (ATTR_NON_FINITE, AttrValue::Text(accum.non_finite_samples.to_string()))]);
    write_rgb(path, &accum.mean(), &attributes, overwrite)
}

/// Writes the sums of a reference part (samples `accum.first..` of the render of `provenance`).
pub fn write_reference_part(
    path: &Path,
    accum: &ReferenceAccum,
    provenance: &Provenance,
    scene: &str,
    of: PartSpec,
    overwrite: bool,
) -> Result<(), StreamError> {
    let mut ch = ExrChannels::new(accum.width as usize, accum.height as usize);
    // The part's own mean, for viewing only.
    put_rgb(&mut ch, "", &accum.mean());
    insert_sums3(&mut ch, "sum.", ["R", "G", "B"], &accum.sum);
    Provenance { batches: None, ..provenance.clone() }.write_to(&mut ch.attributes);
    let a = &mut ch.attributes;
    a.insert(KIND_ATTR.into(), AttrValue::Text(REFERENCE_KIND.into()));
    a.insert(ATTR_FIRST.into(), AttrValue::Int(accum.first as i32));
    a.insert(ATTR_END.into(), AttrValue::Int((accum.first + accum.samples_done) as i32));
    a.insert(ATTR_OF.into(), AttrValue::Text(of.to_string()));
    a.insert(ATTR_SCENE.into(), AttrValue::Text(scene.into()));
    a.insert(ATTR_NON_FINITE.into(), AttrValue::Text(accum.non_finite_samples.to_string()));
    ch.write(path, overwrite)
}

/// Reads the reference part at `path` whose header `header` was read already.
pub(crate) fn read_reference_part(path: &Path, header: &PartHeader) -> Result<ReferenceAccum, StreamError> {
    let mut ch = ExrChannels::read(path)?;
    let p = &header.provenance;
    Ok(ReferenceAccum {
        width: p.width,
        height: p.height,
        sum: take_sums3(&mut ch, path, "sum.", ["R", "G", "B"])?,
        first: header.range.start,
        samples_done: header.range.len() as u32,
        seed: p.seed.unwrap_or(0),
        max_depth: p.max_depth.unwrap_or(-1),
        rr_depth: p.rr_depth.unwrap_or(0),
        non_finite_samples: header.non_finite,
    })
}
