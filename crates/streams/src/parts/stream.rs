//! The part of a stream render (a range of its batches: their means and the exact sums of
//! their samples) and the whole stream file that parts add up to.
use super::header::{PartHeader, ATTR_END, ATTR_FIRST, ATTR_NON_FINITE, ATTR_OF, ATTR_SCENE, KIND_ATTR, STREAMS_KIND};
use super::spec::PartSpec;
use crate::error::{StreamError, SumsError};
use crate::exact::{self, insert_sums, insert_sums3, take_sums, take_sums3};
use crate::exr_io::{put_rgb, take_rgb, AttrValue, ExrChannels};
use crate::image::Image;
use crate::provenance::Provenance;
use crate::stream_set::{batch_prefix, Features, Stream, StreamMeta, StreamSet};
use std::ops::Range;
use std::path::Path;

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
    pub fn append(&mut self, next: StreamPart) -> Result<(), SumsError> {
        if (next.width, next.height, next.spp, next.batches) != (self.width, self.height, self.spp, self.batches) {
            return Err(SumsError::Streams("the parts are of different renders".into()));
        }
        if next.range.start != self.range.end {
            return Err(SumsError::Streams(format!("batches {:?} do not follow {:?}", next.range, self.range)));
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
                // Every cvtrace crate has the workspace's version.
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
    pub(crate) fn read(path: &Path, header: &PartHeader) -> Result<StreamPart, StreamError> {
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
