//! The in-memory stream set and its file form (see `docs/stream-format.md`).
use crate::exr_io::{put_rgb, take_rgb, AttrValue, ExrChannels};
use crate::{Image, StreamError};
use std::collections::BTreeMap;
use std::path::Path;

/// One sample stream: the mean of all `n` samples and `B` batch means over fixed,
/// contiguous ranges of sample indices (the same range in every pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct Stream {
    pub mean: Image,
    pub batches: Vec<Image>,
}

impl Stream {
    /// A stream whose mean is the mean of its batches (equal-size batches).
    pub fn from_batches(batches: Vec<Image>) -> Self {
        Stream { mean: Image::mean_of(&batches), batches }
    }
}

/// First-hit features averaged over the samples of a pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    pub albedo: Image,
    pub normal: Image,
    pub depth: Vec<f32>,
}

/// Provenance recorded in the file header.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct StreamMeta {
    /// Samples per pixel of *each* stream.
    pub spp: u32,
    pub seed: u64,
    /// Mitsuba convention: longest path in segments from the camera, -1 unlimited.
    pub max_depth: i32,
    pub scene: String,
    pub version: String,
    /// Samples that were NaN or infinite, replaced by zero, over both streams.
    pub non_finite_samples: u64,
    /// Renderer settings that shaped the samples beyond the fields above, stored as
    /// `cvtrace.<key>` text attributes; other `cvtrace.*` text attributes of a file read back
    /// land here too (cvtrace's own renderer records a [`crate::Provenance`], whose text
    /// fields, such as `traversal`, read back here).
    pub settings: BTreeMap<String, String>,
}

/// Two paired renders of the same image plus features: the input of every estimator.
#[derive(Clone, Debug, PartialEq)]
pub struct StreamSet {
    pub width: usize,
    pub height: usize,
    pub pt: Stream,
    pub crn: Stream,
    pub features: Option<Features>,
    pub meta: StreamMeta,
}

const ATTR_SPP: &str = "cvtrace.spp";
const ATTR_BATCHES: &str = "cvtrace.batches";
const ATTR_SEED: &str = "cvtrace.seed";
const ATTR_MAX_DEPTH: &str = "cvtrace.maxDepth";
const ATTR_SCENE: &str = "cvtrace.scene";
const ATTR_VERSION: &str = "cvtrace.version";
const ATTR_NON_FINITE: &str = "cvtrace.nonFiniteSamples";
const KNOWN_ATTRS: [&str; 7] = [ATTR_SPP, ATTR_BATCHES, ATTR_SEED, ATTR_MAX_DEPTH, ATTR_SCENE, ATTR_VERSION, ATTR_NON_FINITE];
const ATTR_PREFIX: &str = "cvtrace.";

/// The stream mean must be the mean of its batch means (to rounding, with room for writers that
/// sum in f32): otherwise every estimator that uses both would silently mix two different images.
fn check_batch_means(origin: &Path, name: &str, s: &Stream) -> Result<(), StreamError> {
    let inv_b = 1.0 / s.batches.len() as f64;
    for (i, mean) in s.mean.pixels.iter().enumerate() {
        for c in 0..3 {
            let (mut sum, mut scale) = (0.0f64, mean[c].abs() as f64);
            for batch in &s.batches {
                let v = batch.pixels[i][c] as f64;
                sum += v;
                scale = scale.max(v.abs());
            }
            let of_batches = sum * inv_b;
            if (of_batches - mean[c] as f64).abs() > 1e-3 * scale + 1e-6 {
                let (x, y) = (i % s.mean.width, i / s.mean.width);
                return Err(StreamError::invalid(
                    origin,
                    format!(
                        "{name}.{} at pixel ({x}, {y}) is {} but the mean of its batches is {of_batches}: the batches are not the stream's samples",
                        ["R", "G", "B"][c],
                        mean[c]
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Channel prefix of batch `b` of `stream` ("pt" or "crn"), e.g. `pt.b03.`.
pub fn batch_prefix(stream: &str, b: usize) -> String {
    format!("{stream}.b{b:02}.")
}

impl StreamSet {
    pub fn batch_count(&self) -> usize {
        self.pt.batches.len()
    }

    /// Checks sizes, batch counts and finiteness; `origin` names the source in errors.
    pub fn validate(&self, origin: &Path) -> Result<(), StreamError> {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return Err(StreamError::invalid(origin, "image is empty"));
        }
        let b = self.pt.batches.len();
        if b == 0 || b != self.crn.batches.len() {
            return Err(StreamError::invalid(
                origin,
                format!("pt has {} batches and crn {}; both need the same non-zero count", b, self.crn.batches.len()),
            ));
        }
        let named = [("pt", &self.pt), ("crn", &self.crn)];
        for (name, s) in named {
            let all = std::iter::once((format!("{name}."), &s.mean))
                .chain(s.batches.iter().enumerate().map(|(i, im)| (batch_prefix(name, i), im)));
            for (prefix, im) in all {
                if im.width != w || im.height != h {
                    return Err(StreamError::invalid(origin, format!("{prefix}RGB is {}x{}, expected {w}x{h}", im.width, im.height)));
                }
                if let Some((x, y, c)) = im.find_non_finite() {
                    return Err(StreamError::NonFinite {
                        path: origin.to_path_buf(),
                        channel: format!("{prefix}{}", ["R", "G", "B"][c]),
                        x,
                        y,
                    });
                }
            }
        }
        for (name, s) in named {
            check_batch_means(origin, name, s)?;
        }
        if self.meta.spp > 0 && !(self.meta.spp as usize).is_multiple_of(b) {
            return Err(StreamError::invalid(origin, format!("{} spp per stream do not split into {b} equal batches", self.meta.spp)));
        }
        if let Some(f) = &self.features {
            if f.albedo.width != w || f.albedo.height != h || f.normal.width != w || f.normal.height != h || f.depth.len() != w * h {
                return Err(StreamError::invalid(origin, "feature channels do not match the image size"));
            }
            let non_finite = |name: &str, im: &Image, channels: [&str; 3]| {
                im.find_non_finite().map(|(x, y, c)| StreamError::NonFinite {
                    path: origin.to_path_buf(),
                    channel: format!("{name}.{}", channels[c]),
                    x,
                    y,
                })
            };
            if let Some(e) = non_finite("albedo", &f.albedo, ["R", "G", "B"]).or_else(|| non_finite("normal", &f.normal, ["X", "Y", "Z"])) {
                return Err(e);
            }
            if let Some(i) = f.depth.iter().position(|d| !d.is_finite()) {
                return Err(StreamError::NonFinite { path: origin.to_path_buf(), channel: "depth.Z".into(), x: i % w, y: i / w });
            }
        }
        Ok(())
    }

    /// Writes the stream file atomically (refusing to replace an existing file unless `overwrite`).
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<(), StreamError> {
        self.to_exr(path)?.write(path, overwrite)
    }

    /// The file's channels and header, validated (`path` names it in errors), for a writer
    /// that adds attributes of its own (a renderer's [`crate::Provenance`]) before writing.
    pub fn to_exr(&self, path: &Path) -> Result<ExrChannels, StreamError> {
        self.validate(path)?;
        let mut ch = ExrChannels::new(self.width, self.height);
        for (name, s) in [("pt", &self.pt), ("crn", &self.crn)] {
            put_rgb(&mut ch, &format!("{name}."), &s.mean);
            for (b, im) in s.batches.iter().enumerate() {
                put_rgb(&mut ch, &batch_prefix(name, b), im);
            }
        }
        // The top-level layer is the picture: the mean of both streams, so that `oiiotool x.exr
        // -o x.png` and image viewers show the image. Readers of the streams ignore it.
        let picture = Image {
            width: self.width,
            height: self.height,
            pixels: self
                .pt
                .mean
                .pixels
                .iter()
                .zip(&self.crn.mean.pixels)
                .map(|(h, g)| std::array::from_fn(|c| 0.5 * (h[c] + g[c])))
                .collect(),
        };
        put_rgb(&mut ch, "", &picture);
        // An opaque alpha, so that a 4-channel export takes it rather than the next layer.
        ch.insert("A", vec![1.0; self.width * self.height]);
        if let Some(f) = &self.features {
            put_rgb(&mut ch, "albedo.", &f.albedo);
            for (c, n) in ["X", "Y", "Z"].iter().enumerate() {
                ch.insert(format!("normal.{n}"), f.normal.channel(c));
            }
            ch.insert("depth.Z", f.depth.clone());
        }
        let m = &self.meta;
        let a = &mut ch.attributes;
        a.insert(ATTR_SPP.into(), AttrValue::Int(m.spp as i32));
        a.insert(ATTR_BATCHES.into(), AttrValue::Int(self.batch_count() as i32));
        a.insert(ATTR_SEED.into(), AttrValue::Text(m.seed.to_string()));
        a.insert(ATTR_MAX_DEPTH.into(), AttrValue::Int(m.max_depth));
        a.insert(ATTR_SCENE.into(), AttrValue::Text(m.scene.clone()));
        a.insert(ATTR_VERSION.into(), AttrValue::Text(m.version.clone()));
        a.insert(ATTR_NON_FINITE.into(), AttrValue::Text(m.non_finite_samples.to_string()));
        for (k, v) in &m.settings {
            a.insert(format!("{ATTR_PREFIX}{k}"), AttrValue::Text(v.clone()));
        }
        Ok(ch)
    }

    /// Reads and validates a stream file. Features are optional; everything else is required.
    pub fn read(path: &Path) -> Result<StreamSet, StreamError> {
        let mut ch = ExrChannels::read(path)?;
        let (w, h) = (ch.width, ch.height);
        // An attribute of another EXR type (a `v2f` spp) must not read as an absent one.
        if let Some((k, kind)) = ch.other_attributes.iter().find(|(k, _)| KNOWN_ATTRS.contains(&k.as_str())) {
            return Err(StreamError::invalid(
                path,
                format!("attribute {k} has EXR type {kind}, not int or string (docs/stream-format.md)"),
            ));
        }
        let batches = match ch.attr(ATTR_BATCHES) {
            Some(AttrValue::Int(b)) if *b > 0 => *b as usize,
            Some(other) => {
                return Err(StreamError::invalid(path, format!("attribute {ATTR_BATCHES} = {} is not a positive integer", other.as_text())))
            }
            None => count_batches(&ch),
        };
        if batches == 0 && ch.channels.contains_key("R") && !ch.channels.contains_key("pt.R") {
            return Err(StreamError::invalid(
                path,
                "is an RGB image (a reference or a reconstruction), not a PT/CRN stream file: render one without --reference",
            ));
        }
        if batches == 0 {
            return Err(StreamError::MissingChannel { path: path.to_path_buf(), channel: "pt.b00.R".into() });
        }
        // The header's count is only a claim: a corrupt one (2³¹ − 1) must not size allocations.
        let found = count_batches(&ch);
        if batches > found {
            return Err(StreamError::invalid(
                path,
                format!(
                    "attribute {ATTR_BATCHES} = {batches}, but channel {}R is missing: the file holds {found} batches",
                    batch_prefix("pt", found)
                ),
            ));
        }
        let mut streams = Vec::with_capacity(2);
        for name in ["pt", "crn"] {
            let mean = take_rgb(&mut ch, path, &format!("{name}."))?;
            let mut bs = Vec::with_capacity(batches);
            for b in 0..batches {
                bs.push(take_rgb(&mut ch, path, &batch_prefix(name, b))?);
            }
            streams.push(Stream { mean, batches: bs });
        }
        // Batch channels left over mean the count is wrong (or has a gap): reading fewer batches
        // than the file holds would silently drop samples.
        if let Some(extra) = ch.channels.keys().find(|k| k.starts_with("pt.b") || k.starts_with("crn.b")) {
            return Err(StreamError::invalid(
                path,
                format!("has channel {extra} beyond its {batches} batches (b00 to b{:02})", batches - 1),
            ));
        }
        const FEATURES: [&str; 7] = ["albedo.R", "albedo.G", "albedo.B", "normal.X", "normal.Y", "normal.Z", "depth.Z"];
        let present: Vec<&str> = FEATURES.iter().copied().filter(|c| ch.channels.contains_key(*c)).collect();
        if !present.is_empty() && present.len() < FEATURES.len() {
            let missing: Vec<&str> = FEATURES.iter().copied().filter(|c| !present.contains(c)).collect();
            return Err(StreamError::invalid(
                path,
                format!("has some feature channels but not {}: the features come as a group, all or none", missing.join(", ")),
            ));
        }
        let features = if !present.is_empty() {
            let albedo = take_rgb(&mut ch, path, "albedo.")?;
            let nx = ch.take(path, "normal.X")?;
            let ny = ch.take(path, "normal.Y")?;
            let nz = ch.take(path, "normal.Z")?;
            let depth = ch.take(path, "depth.Z")?;
            Some(Features { albedo, normal: Image::from_channels(w, h, [&nx, &ny, &nz]), depth })
        } else {
            None
        };
        let text = |k: &str| ch.attr(k).map(|v| v.as_text()).unwrap_or_default();
        // Absent attributes (other renderers) read as unknown; present ones must make sense.
        let bad = |k: &str, v: &AttrValue, expected: &str| {
            StreamError::invalid(path, format!("attribute {k} = {} is not {expected}", v.as_text()))
        };
        let spp = match ch.attr(ATTR_SPP) {
            None => 0,
            Some(AttrValue::Int(i)) if *i > 0 => *i as u32,
            Some(v) => return Err(bad(ATTR_SPP, v, "a positive integer")),
        };
        let seed = match ch.attr(ATTR_SEED) {
            None => 0,
            Some(AttrValue::Int(i)) if *i >= 0 => *i as u64,
            Some(v @ AttrValue::Text(t)) => t.parse().map_err(|_| bad(ATTR_SEED, v, "an unsigned 64-bit integer"))?,
            Some(v) => return Err(bad(ATTR_SEED, v, "an unsigned 64-bit integer")),
        };
        let max_depth = match ch.attr(ATTR_MAX_DEPTH) {
            None => -1,
            Some(AttrValue::Int(i)) if *i == -1 || *i >= 1 => *i,
            Some(v) => return Err(bad(ATTR_MAX_DEPTH, v, "-1 or a positive integer")),
        };
        // A count the reader cannot parse must not read as "no sample was replaced".
        let non_finite_samples = match ch.attr(ATTR_NON_FINITE) {
            None => 0,
            Some(AttrValue::Int(i)) if *i >= 0 => *i as u64,
            Some(v @ AttrValue::Text(t)) => t.parse().map_err(|_| bad(ATTR_NON_FINITE, v, "an unsigned 64-bit integer"))?,
            Some(v) => return Err(bad(ATTR_NON_FINITE, v, "an unsigned 64-bit integer")),
        };
        let meta = StreamMeta {
            spp,
            seed,
            max_depth,
            scene: text(ATTR_SCENE),
            version: text(ATTR_VERSION),
            non_finite_samples,
            settings: ch
                .attributes
                .iter()
                .filter(|(k, v)| !KNOWN_ATTRS.contains(&k.as_str()) && matches!(v, AttrValue::Text(_)))
                .filter_map(|(k, v)| Some((k.strip_prefix(ATTR_PREFIX)?.to_string(), v.as_text())))
                .collect(),
        };
        let crn = streams.pop().unwrap();
        let pt = streams.pop().unwrap();
        let set = StreamSet { width: w, height: h, pt, crn, features, meta };
        set.validate(path)?;
        Ok(set)
    }
}

fn count_batches(ch: &ExrChannels) -> usize {
    (0..).take_while(|b| ch.channels.contains_key(&format!("{}R", batch_prefix("pt", *b)))).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn synthetic(w: usize, h: usize, b: usize) -> StreamSet {
        let mk = |s: f32| (0..b).map(|i| Image::from_fn(w, h, |x, y| [s + x as f32, y as f32, i as f32])).collect::<Vec<_>>();
        StreamSet {
            width: w,
            height: h,
            pt: Stream::from_batches(mk(0.0)),
            crn: Stream::from_batches(mk(1.0)),
            features: Some(Features {
                albedo: Image::from_fn(w, h, |_, _| [0.5; 3]),
                normal: Image::from_fn(w, h, |_, _| [0.0, 0.0, 1.0]),
                depth: vec![2.0; w * h],
            }),
            meta: StreamMeta {
                spp: 8,
                seed: 1 << 40,
                max_depth: 8,
                scene: "s.gltf".into(),
                version: "0.1.0".into(),
                non_finite_samples: 3,
                settings: [("traversal".to_string(), "robust".to_string())].into(),
            },
        }
    }

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.streams.exr");
        let s = synthetic(7, 5, 4);
        s.write(&p, false).unwrap();
        assert_eq!(StreamSet::read(&p).unwrap(), s);
    }

    #[test]
    fn missing_batch_channel_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.exr");
        synthetic(3, 3, 2).write(&p, false).unwrap();
        let mut ch = ExrChannels::read(&p).unwrap();
        ch.channels.remove("crn.b01.G");
        let q = dir.path().join("t.exr");
        ch.write(&q, false).unwrap();
        let e = StreamSet::read(&q).unwrap_err().to_string();
        assert!(e.contains("t.exr") && e.contains("crn.b01.G"), "{e}");
    }

    #[test]
    fn nan_is_rejected_with_its_channel() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.exr");
        synthetic(3, 3, 2).write(&p, false).unwrap();
        let mut ch = ExrChannels::read(&p).unwrap();
        ch.channels.get_mut("pt.b01.R").unwrap()[4] = f32::NAN;
        let q = dir.path().join("nan.exr");
        ch.write(&q, false).unwrap();
        let e = StreamSet::read(&q).unwrap_err().to_string();
        assert!(e.contains("nan.exr") && e.contains("pt.b01.R") && e.contains("(1, 1)"), "{e}");
    }

    /// Writes `synthetic(4, 3, 4)`, applies `edit` to its channels and attributes, and returns
    /// the error of reading the edited file back.
    fn read_error_after(edit: impl FnOnce(&mut ExrChannels)) -> String {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.exr");
        synthetic(4, 3, 4).write(&p, false).unwrap();
        let mut ch = ExrChannels::read(&p).unwrap();
        edit(&mut ch);
        let q = dir.path().join("edited.exr");
        ch.write(&q, false).unwrap();
        StreamSet::read(&q).expect_err("the edited file must be refused").to_string()
    }

    #[test]
    fn inconsistent_or_incomplete_files_are_refused() {
        // A stream mean that is not the mean of its batches.
        let e = read_error_after(|ch| ch.channels.get_mut("crn.G").unwrap()[5] += 0.01);
        assert!(e.contains("edited.exr") && e.contains("crn.G at pixel (1, 1)") && e.contains("mean of its batches"), "{e}");
        // Rounding-level differences are fine: the round trip above already checks that; here
        // one batch moves by less than the tolerance.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.exr");
        let mut s = synthetic(4, 3, 4);
        s.pt.batches[0].pixels[5][0] += 1e-5; // pixel (1, 1), whose value is 1
        s.write(&p, false).unwrap();
        // Half a feature group.
        let e = read_error_after(|ch| {
            ch.channels.remove("depth.Z");
        });
        assert!(e.contains("but not depth.Z") && e.contains("all or none"), "{e}");
        // Non-finite features.
        let e = read_error_after(|ch| ch.channels.get_mut("depth.Z").unwrap()[2] = f32::INFINITY);
        assert!(e.contains("depth.Z") && e.contains("(2, 0)"), "{e}");
        // Header attributes that are present but meaningless.
        let e = read_error_after(|ch| {
            ch.attributes.insert(ATTR_SPP.into(), AttrValue::Int(-8));
        });
        assert!(e.contains("cvtrace.spp = -8 is not a positive integer"), "{e}");
        let e = read_error_after(|ch| {
            ch.attributes.insert(ATTR_SPP.into(), AttrValue::Int(10));
        });
        assert!(e.contains("10 spp per stream do not split into 4 equal batches"), "{e}");
        // More batch channels than the header's count.
        let e = read_error_after(|ch| {
            ch.attributes.insert(ATTR_BATCHES.into(), AttrValue::Int(2));
            ch.attributes.insert(ATTR_SPP.into(), AttrValue::Int(8));
        });
        assert!(e.contains("beyond its 2 batches"), "{e}");
        let e = read_error_after(|ch| {
            ch.attributes.insert(ATTR_SEED.into(), AttrValue::Text("seven".into()));
        });
        assert!(e.contains("cvtrace.seed = seven"), "{e}");
    }

    #[test]
    fn an_absurd_batch_count_in_the_header_is_an_error_not_an_allocation() {
        // Found by fuzzing: `cvtrace.batches` = 2³¹ − 1 sized a Vec of 2³¹ images, and the
        // process aborted ("memory allocation of 85899345880 bytes failed").
        for b in [i32::MAX, 1_000_000_000, 5] {
            let e = read_error_after(|ch| {
                ch.attributes.insert(ATTR_BATCHES.into(), AttrValue::Int(b));
                ch.attributes.remove(ATTR_SPP);
            });
            assert!(e.contains("edited.exr") && e.contains(&format!("cvtrace.batches = {b}")) && e.contains("pt.b04.R is missing"), "{e}");
        }
    }

    #[test]
    fn an_unreadable_count_of_replaced_samples_is_refused() {
        // Found by fuzzing: "abc", "-1" or a count beyond u64 read as 0 replaced samples.
        for bad in ["abc", "-1", "18446744073709551616", " 16", "4.5"] {
            let e = read_error_after(|ch| {
                ch.attributes.insert(ATTR_NON_FINITE.into(), AttrValue::Text(bad.into()));
            });
            assert!(e.contains("edited.exr") && e.contains(&format!("cvtrace.nonFiniteSamples = {bad} is not")), "{e}");
        }
        let e = read_error_after(|ch| {
            ch.attributes.insert(ATTR_NON_FINITE.into(), AttrValue::Int(-3));
        });
        assert!(e.contains("cvtrace.nonFiniteSamples = -3"), "{e}");
        // Written as an int by another renderer: read.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.exr");
        synthetic(4, 3, 4).write(&p, false).unwrap();
        let mut ch = ExrChannels::read(&p).unwrap();
        ch.attributes.insert(ATTR_NON_FINITE.into(), AttrValue::Int(12));
        let q = dir.path().join("int.exr");
        ch.write(&q, false).unwrap();
        assert_eq!(StreamSet::read(&q).unwrap().meta.non_finite_samples, 12);
    }
}
