//! The check that part files make up one render, each of its units in exactly one of them,
//! and their merge into the file one render writes.
use super::header::{PartHeader, STREAMS_KIND};
use super::reference::{read_reference_part, write_reference};
use super::spec::PartError;
use super::stream::{write_stream_file, StreamPart};
use crate::atomic::{check_extension, check_writable};
use crate::error::StreamError;
use crate::provenance::describe_all;
use crate::reference::ReferenceAccum;
use std::path::{Path, PathBuf};

/// What [`merge`] wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Merged {
    /// `streams-v1` or `reference-v1`.
    pub kind: String,
    pub parts: usize,
    /// Batches (stream files) or samples per pixel (references).
    pub units: u32,
}

/// Checks that the headers of `paths` are the parts of one render, each of its units in exactly
/// one of them; returns them in range order. Reads headers only.
pub fn check_parts(paths: &[PathBuf]) -> Result<Vec<PartHeader>, PartError> {
    if paths.is_empty() {
        return Err(PartError::Parts("no parts given".into()));
    }
    let mut headers = paths.iter().map(|p| PartHeader::read(p)).collect::<Result<Vec<_>, _>>()?;
    let first = headers[0].clone();
    let name = |h: &PartHeader| format!("{} ({})", h.path.display(), h.describe_range());
    for h in &headers[1..] {
        if h.kind != first.kind {
            return Err(PartError::Parts(format!(
                "{} is a part of a {} render, {} of a {} render",
                name(h),
                if h.kind == STREAMS_KIND { "stream" } else { "reference" },
                name(&first),
                if first.kind == STREAMS_KIND { "stream" } else { "reference" },
            )));
        }
        let mut diff = describe_all(&first.provenance.differences(&h.provenance), "this part");
        if h.provenance.version != first.provenance.version {
            let v = |p: &PartHeader| p.provenance.version.clone().unwrap_or_default();
            diff = [diff, format!("version {} (this part) vs {}", v(h), v(&first))]
                .into_iter()
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>()
                .join(", ");
        }
        if h.scene != first.scene {
            diff = [diff, format!("scene path {:?} (this part) vs {:?}", h.scene, first.scene)]
                .into_iter()
                .filter(|s| !s.is_empty())
                .collect::<Vec<_>>()
                .join(", ");
        }
        if !diff.is_empty() {
            return Err(PartError::Parts(format!(
                "{} is not a part of the same render as {}: {}",
                name(h),
                name(&first),
                diff.replace("(now)", "(the other)")
            )));
        }
    }
    headers.sort_by_key(|h| (h.range.start, h.range.end));
    let total = first.total();
    let mut end = 0;
    for (i, h) in headers.iter().enumerate() {
        if h.range.start < end {
            let prev = &headers[i - 1];
            let what = if prev.range == h.range { "is the same part as" } else { "overlaps" };
            let unit = if h.kind == STREAMS_KIND { "batch" } else { "sample" };
            return Err(PartError::Parts(format!("{} {what} {}: every {unit} must be in exactly one part", name(h), name(prev))));
        }
        if h.range.start > end {
            return Err(PartError::Parts(format!(
                "{} {end}..{} of {total} are in none of the parts given (a part is missing before {})",
                h.unit(),
                h.range.start,
                name(h)
            )));
        }
        end = h.range.end;
    }
    if end < total {
        return Err(PartError::Parts(format!(
            "{} {end}..{total} of {total} are in none of the parts given (a part is missing after {})",
            first.unit(),
            name(headers.last().expect("at least one part"))
        )));
    }
    Ok(headers)
}

/// Merges the parts at `paths` into `output`: exactly the file one render of every batch (or
/// pass) writes. Nothing is written unless every part is there once, belongs to the same render
/// and reads.
pub fn merge(paths: &[PathBuf], output: &Path, overwrite: bool) -> Result<Merged, PartError> {
    check_extension(output, "exr")?;
    check_writable(output, overwrite)?;
    let headers = check_parts(paths)?;
    let first = &headers[0];
    let p = &first.provenance;
    let units = first.total();
    let described = |h: &PartHeader, e: StreamError| PartError::Parts(format!("{} ({}): {e}", h.path.display(), h.describe_range()));
    if first.kind == STREAMS_KIND {
        let mut whole: Option<StreamPart> = None;
        for h in &headers {
            let part = StreamPart::read(&h.path, h).map_err(|e| described(h, e))?;
            match &mut whole {
                None => whole = Some(part),
                Some(w) => w.append(part)?,
            }
        }
        let whole = whole.expect("at least one part");
        let mut set = whole.into_stream_set(p.seed.unwrap_or(0), p.max_depth.unwrap_or(-1)).expect("the parts cover every batch");
        set.meta.scene = first.scene.clone();
        write_stream_file(output, &set, p, overwrite)?;
    } else {
        let mut whole: Option<ReferenceAccum> = None;
        for h in &headers {
            let part = read_reference_part(&h.path, h).map_err(|e| described(h, e))?;
            match &mut whole {
                None => whole = Some(part),
                Some(w) => w.append(&part)?,
            }
        }
        write_reference(output, &whole.expect("at least one part"), p, &first.scene, overwrite)?;
    }
    Ok(Merged { kind: first.kind.clone(), parts: headers.len(), units })
}
