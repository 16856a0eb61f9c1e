//! Parts of a render, made on any machine and merged into exactly the file one render writes.
//!
//! A part of a stream render is a contiguous range of whole batches (both streams); a part of
//! a reference a contiguous range of whole passes. A part stores what its range contributes
//! and nothing that depends on the others: the batch means of its batches (a batch never
//! straddles two parts, so they are the one-shot render's bit for bit) and the exact sums of
//! its samples ([`crate::exact`]), which add up to the one-shot render's sums in any order.
//! The merge adds the sums, divides by the sample count and writes the file with the same
//! code as the one-shot render. docs/stream-format.md ("Parts") describes the files.
use crate::exact::{self, insert_sums, insert_sums3, take_sums, take_sums3};
use crate::render::{ReferenceAccum, RenderError};
use cvtrace_streams::atomic::{check_extension, check_writable};
use cvtrace_streams::exr_io::{put_rgb, take_rgb, write_rgb, AttrValue, ExrChannels};
use cvtrace_streams::provenance::{describe_all, Field, Provenance};
use cvtrace_streams::stream_set::batch_prefix;
use cvtrace_streams::{Features, Image, Stream, StreamError, StreamMeta, StreamSet};
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
const ATTR_SCENE: &str = "cvtrace.scene";
const ATTR_NON_FINITE: &str = "cvtrace.nonFiniteSamples";

/// Why a part could not be made or the parts not merged. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum PartError {
    #[error("--part {0}")]
    Spec(String),
    #[error(transparent)]
    File(#[from] StreamError),
    #[error(transparent)]
    Render(#[from] RenderError),
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

/// Exact sums of one range of samples of a stream render, per pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamSums {
    pub pt: Vec<[i128; 3]>,
    pub crn: Vec<[i128; 3]>,
    /// First-hit features over the PT samples.
    pub albedo: Vec<[i128; 3]>,
    pub normal: Vec<[i128; 3]>,
    pub depth: Vec<i128>,
}

impl StreamSums {
    pub fn zero(pixels: usize) -> StreamSums {
        let z = vec![[0; 3]; pixels];
        StreamSums { pt: z.clone(), crn: z.clone(), albedo: z.clone(), normal: z, depth: vec![0; pixels] }
    }

    fn add(&mut self, o: &StreamSums) {
        for (a, b) in [(&mut self.pt, &o.pt), (&mut self.crn, &o.crn), (&mut self.albedo, &o.albedo), (&mut self.normal, &o.normal)] {
            a.iter_mut().zip(b).for_each(|(a, b)| exact::add3(a, *b));
        }
        self.depth.iter_mut().zip(&o.depth).for_each(|(a, b)| *a += b);
    }
}

/// Batches `range` of a stream render of `batches` batches of `spp / batches` samples.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamPart {
    pub width: usize,
    pub height: usize,
    /// Samples per pixel of each stream in the whole render.
    pub spp: u32,
    /// Batches per stream in the whole render.
    pub batches: u32,
    pub range: Range<u32>,
    /// The batch means of the range, in order.
    pub pt: Vec<Image>,
    pub crn: Vec<Image>,
    pub sums: StreamSums,
    pub non_finite: u64,
}

impl StreamPart {
    /// Adds the batches of `next`, which must follow these.
    pub fn append(&mut self, next: StreamPart) -> Result<(), RenderError> {
        if (next.width, next.height, next.spp, next.batches) != (self.width, self.height, self.spp, self.batches) {
            return Err(RenderError::InvalidSettings("the parts are of different renders".into()));
        }
        if next.range.start != self.range.end {
            return Err(RenderError::InvalidSettings(format!("batches {:?} do not follow {:?}", next.range, self.range)));
        }
        self.sums.add(&next.sums);
        self.pt.extend(next.pt);
        self.crn.extend(next.crn);
        self.range.end = next.range.end;
        self.non_finite += next.non_finite;
        Ok(())
    }

    /// The stream set of a part of every batch (`None` for a part of some), its means the
    /// exact sums divided by `spp`; `meta.scene` is left empty for the caller.
    pub fn into_stream_set(self, seed: u64, max_depth: i32) -> Option<StreamSet> {
        if self.range != (0..self.batches) {
            return None;
        }
        let (w, h, n) = (self.width, self.height, self.spp as u64);
        let image = |sums: &[[i128; 3]]| Image { width: w, height: h, pixels: sums.iter().map(|s| exact::mean3(*s, n)).collect() };
        let s = &self.sums;
        let (pt_mean, crn_mean, albedo, normal) = (image(&s.pt), image(&s.crn), image(&s.albedo), image(&s.normal));
        let depth = s.depth.iter().map(|d| exact::mean(*d, n)).collect();
        Some(StreamSet {
            width: w,
            height: h,
            pt: Stream { mean: pt_mean, batches: self.pt },
            crn: Stream { mean: crn_mean, batches: self.crn },
            features: Some(Features { albedo, normal, depth }),
            meta: StreamMeta {
                spp: self.spp,
                seed,
                max_depth,
                scene: String::new(),
                version: env!("CARGO_PKG_VERSION").to_string(),
                non_finite_samples: self.non_finite,
                settings: Default::default(),
            },
        })
    }

    /// Writes the part to `path` atomically with the whole render's `provenance`.
    pub fn write(&self, path: &Path, provenance: &Provenance, scene: &str, of: PartSpec, overwrite: bool) -> Result<(), StreamError> {
        self.to_exr(provenance, scene, of).write(path, overwrite)
    }

    /// The part file's channels and header.
    pub fn to_exr(&self, provenance: &Provenance, scene: &str, of: PartSpec) -> ExrChannels {
        let mut ch = ExrChannels::new(self.width, self.height);
        for (name, batches) in [("pt", &self.pt), ("crn", &self.crn)] {
            for (b, im) in self.range.clone().zip(batches) {
                put_rgb(&mut ch, &batch_prefix(name, b as usize), im);
            }
        }
        let rgb = ["R", "G", "B"];
        insert_sums3(&mut ch, "sum.pt.", rgb, &self.sums.pt);
        insert_sums3(&mut ch, "sum.crn.", rgb, &self.sums.crn);
        insert_sums3(&mut ch, "sum.albedo.", rgb, &self.sums.albedo);
        insert_sums3(&mut ch, "sum.normal.", ["X", "Y", "Z"], &self.sums.normal);
        insert_sums(&mut ch, "sum.depth.Z", self.sums.depth.iter().copied());
        provenance.write_to(&mut ch.attributes);
        let a = &mut ch.attributes;
        a.insert(KIND_ATTR.into(), AttrValue::Text(STREAMS_KIND.into()));
        a.insert(ATTR_FIRST.into(), AttrValue::Int(self.range.start as i32));
        a.insert(ATTR_END.into(), AttrValue::Int(self.range.end as i32));
        a.insert(ATTR_OF.into(), AttrValue::Text(of.to_string()));
        a.insert(ATTR_SCENE.into(), AttrValue::Text(scene.into()));
        a.insert(ATTR_NON_FINITE.into(), AttrValue::Text(self.non_finite.to_string()));
        ch
    }

    /// Reads the part at `path` whose header `header` was read already.
    fn read(path: &Path, header: &PartHeader) -> Result<StreamPart, StreamError> {
        let mut ch = ExrChannels::read(path)?;
        let p = &header.provenance;
        let (spp, batches) = (p.spp.unwrap_or(0), p.batches.unwrap_or(0));
        let mut pt = Vec::new();
        let mut crn = Vec::new();
        for b in header.range.clone() {
            pt.push(take_rgb(&mut ch, path, &batch_prefix("pt", b as usize))?);
            crn.push(take_rgb(&mut ch, path, &batch_prefix("crn", b as usize))?);
        }
        let rgb = ["R", "G", "B"];
        let sums = StreamSums {
            pt: take_sums3(&mut ch, path, "sum.pt.", rgb)?,
            crn: take_sums3(&mut ch, path, "sum.crn.", rgb)?,
            albedo: take_sums3(&mut ch, path, "sum.albedo.", rgb)?,
            normal: take_sums3(&mut ch, path, "sum.normal.", ["X", "Y", "Z"])?,
            depth: take_sums(&mut ch, path, "sum.depth.Z")?,
        };
        Ok(StreamPart {
            width: ch.width,
            height: ch.height,
            spp,
            batches,
            range: header.range.clone(),
            pt,
            crn,
            sums,
            non_finite: header.non_finite,
        })
    }
}

/// Writes the stream file of `set` with `provenance`: what a one-shot render and a merge both
/// write, so the two are the same bytes.
pub fn write_stream_file(path: &Path, set: &StreamSet, provenance: &Provenance, overwrite: bool) -> Result<(), StreamError> {
    stream_file_exr(path, set, provenance)?.write(path, overwrite)
}

/// The channels and header [`write_stream_file`] writes (`path` names the file in errors).
pub fn stream_file_exr(path: &Path, set: &StreamSet, provenance: &Provenance) -> Result<ExrChannels, StreamError> {
    let mut file = set.to_exr(path)?;
    provenance.write_to(&mut file.attributes);
    Ok(file)
}

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

fn read_reference_part(path: &Path, header: &PartHeader) -> Result<ReferenceAccum, StreamError> {
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

    fn unit(&self) -> &'static str {
        if self.kind == STREAMS_KIND {
            "batches"
        } else {
            "samples"
        }
    }

    /// How many units the whole render has (batches, or samples of a reference).
    fn total(&self) -> u32 {
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
