//! What a render records about how it was made, in every file kind cvtrace writes (stream
//! files, references, reference checkpoints), and the one comparison between two such records.
//!
//! A file may be reused, resumed or extended only when everything that decides its samples
//! agrees with the render asked for now; the record is that set of values, typed, with one EXR
//! attribute type per field in every file kind (docs/stream-format.md, "Provenance").
//!
//! Every field but the size is optional: files from other renderers, or from older cvtrace
//! versions, may lack some. An absent value on either side is never a difference, so such files
//! are compared on what they do record.
use crate::exr_io::{AttrValue, ExrChannels};
use crate::StreamError;
use std::collections::BTreeMap;
use std::path::Path;

/// The traversal of files that do not record one: cvtrace traced only robustly before it
/// recorded the choice.
pub const LEGACY_TRAVERSAL: &str = "robust";

/// One recorded value. The order is the order in which differences are listed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Field {
    Size,
    Seed,
    MaxDepth,
    RrDepth,
    SceneHash,
    Camera,
    Traversal,
    Spp,
    Batches,
}

impl Field {
    /// Every field, in listing order.
    pub const ALL: [Field; 9] = [
        Field::Size,
        Field::Seed,
        Field::MaxDepth,
        Field::RrDepth,
        Field::SceneHash,
        Field::Camera,
        Field::Traversal,
        Field::Spp,
        Field::Batches,
    ];

    /// The name used in messages.
    pub fn name(self) -> &'static str {
        match self {
            Field::Size => "size",
            Field::Seed => "seed",
            Field::MaxDepth => "max depth",
            Field::RrDepth => "rr depth",
            Field::SceneHash => "scene hash",
            Field::Camera => "camera",
            Field::Traversal => "traversal",
            Field::Spp => "spp",
            Field::Batches => "batches",
        }
    }

    /// The header attribute holding the field (the size is the image's own).
    pub fn attribute(self) -> Option<&'static str> {
        match self {
            Field::Size => None,
            Field::Seed => Some(ATTR_SEED),
            Field::MaxDepth => Some(ATTR_MAX_DEPTH),
            Field::RrDepth => Some(ATTR_RR_DEPTH),
            Field::SceneHash => Some(ATTR_SCENE_HASH),
            Field::Camera => Some(ATTR_CAMERA),
            Field::Traversal => Some(ATTR_TRAVERSAL),
            Field::Spp => Some(ATTR_SPP),
            Field::Batches => Some(ATTR_BATCHES),
        }
    }

    /// Whether a different value makes another image, not only other noise: what a reference
    /// must agree on with the renders it scores. Seed, sample counts and the Russian-roulette
    /// depth change the noise only, and the traversal only whether rare rays graze through an
    /// edge.
    pub fn changes_the_image(self) -> bool {
        matches!(self, Field::Size | Field::MaxDepth | Field::SceneHash | Field::Camera)
    }
}

pub const ATTR_SEED: &str = "cvtrace.seed";
pub const ATTR_MAX_DEPTH: &str = "cvtrace.maxDepth";
pub const ATTR_RR_DEPTH: &str = "cvtrace.rrDepth";
pub const ATTR_SCENE_HASH: &str = "cvtrace.sceneHash";
pub const ATTR_CAMERA: &str = "cvtrace.camera";
pub const ATTR_TRAVERSAL: &str = "cvtrace.traversal";
pub const ATTR_SPP: &str = "cvtrace.spp";
pub const ATTR_BATCHES: &str = "cvtrace.batches";
pub const ATTR_VERSION: &str = "cvtrace.version";

/// Everything that decides a render's samples, plus its sample count and batch count where
/// the file kind records them. `None`: not recorded (or, in a record made to compare with,
/// not to be compared).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Provenance {
    pub width: u32,
    pub height: u32,
    /// Text attribute: a `u64` does not fit an EXR `int`.
    pub seed: Option<u64>,
    /// Longest path in segments from the camera, −1 unlimited.
    pub max_depth: Option<i32>,
    pub rr_depth: Option<u32>,
    /// A hash of the loaded scene (geometry, materials, textures, lights, final camera), hex.
    pub scene_hash: Option<String>,
    /// The camera as rendered (eye, target, up, vertical field of view).
    pub camera: Option<String>,
    /// The ray traversal (`robust` or `fast`): a leak through an edge changes a sample.
    pub traversal: Option<String>,
    /// Samples per pixel (per stream in a stream file). A checkpoint does not record it: its
    /// progress is `cvtrace.samplesDone`.
    pub spp: Option<u32>,
    /// Batches per stream (stream files only).
    pub batches: Option<u32>,
    /// The version of the cvtrace that wrote the file: another version may draw other samples
    /// for the same settings. Not part of [`Provenance::differences`]; resuming checks it.
    pub version: Option<String>,
}

/// A field whose recorded value differs from the one asked for now.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Difference {
    pub field: Field,
    pub recorded: String,
    pub now: String,
}

impl Difference {
    /// `"seed 3 (in the file) vs 4 (now)"`, `recorded_in` naming where the recorded value is.
    pub fn describe(&self, recorded_in: &str) -> String {
        let plain = format!("{} {} ({recorded_in}) vs {} (now)", self.field.name(), self.recorded, self.now);
        // A scene hash carries its fingerprint's version before a colon (`fp3:…`); the first
        // ones carried none. Hashes of two versions never match, whatever the scene.
        let version = |h: &str| h.split_once(':').map(|(v, _)| v.to_string());
        match (self.field, version(&self.recorded), version(&self.now)) {
            (Field::SceneHash, old, Some(new)) if old.as_deref() != Some(new.as_str()) => format!(
                "{plain}: the file was recorded with {} scene fingerprint, which cannot be compared with this cvtrace's ({new}); \
                 re-render it, or render with the cvtrace that wrote it",
                old.map_or_else(|| "the unversioned".to_string(), |o| format!("an older ({o})"))
            ),
            _ => plain,
        }
    }
}

/// The differences described and joined with commas, for an error message.
pub fn describe_all(differences: &[Difference], recorded_in: &str) -> String {
    differences.iter().map(|d| d.describe(recorded_in)).collect::<Vec<_>>().join(", ")
}

impl Provenance {
    /// The recorded value of `field` as text, `None` when not recorded.
    pub fn value(&self, field: Field) -> Option<String> {
        match field {
            Field::Size => Some(format!("{}x{}", self.width, self.height)),
            Field::Seed => self.seed.map(|v| v.to_string()),
            Field::MaxDepth => self.max_depth.map(|v| v.to_string()),
            Field::RrDepth => self.rr_depth.map(|v| v.to_string()),
            Field::SceneHash => self.scene_hash.clone(),
            Field::Camera => self.camera.clone(),
            Field::Traversal => self.traversal.clone(),
            Field::Spp => self.spp.map(|v| v.to_string()),
            Field::Batches => self.batches.map(|v| v.to_string()),
        }
    }

    /// The recorded fields as (name, value) pairs in [`Field::ALL`] order, for reports.
    pub fn fields(&self) -> Vec<(&'static str, String)> {
        Field::ALL.iter().filter_map(|&f| Some((f.name(), self.value(f)?))).collect()
    }

    /// The fields in which `recorded` (a file's record) differs from `self` (the render asked
    /// for now), in [`Field::ALL`] order. A value absent on either side is not compared.
    pub fn differences(&self, recorded: &Provenance) -> Vec<Difference> {
        Field::ALL
            .iter()
            .filter_map(|&field| {
                let (now, recorded) = (self.value(field)?, recorded.value(field)?);
                (now != recorded).then_some(Difference { field, recorded, now })
            })
            .collect()
    }

    /// The record without its sample and batch counts: what a resumed or extended render must
    /// agree on (passes add samples in index order, so any later target continues the same
    /// sequence).
    pub fn without_counts(&self) -> Provenance {
        Provenance { spp: None, batches: None, ..self.clone() }
    }

    /// The header attributes of the recorded fields, each with its one type: `int` for depths
    /// and counts, `string` for the rest (the seed is a `u64`).
    pub fn attributes(&self) -> Vec<(&'static str, AttrValue)> {
        let mut out = Vec::new();
        let int = |v: u32| AttrValue::Int(i32::try_from(v).unwrap_or(i32::MAX));
        if let Some(v) = self.seed {
            out.push((ATTR_SEED, AttrValue::Text(v.to_string())));
        }
        if let Some(v) = self.max_depth {
            out.push((ATTR_MAX_DEPTH, AttrValue::Int(v)));
        }
        if let Some(v) = self.rr_depth {
            out.push((ATTR_RR_DEPTH, int(v)));
        }
        for (k, v) in [
            (ATTR_SCENE_HASH, &self.scene_hash),
            (ATTR_CAMERA, &self.camera),
            (ATTR_TRAVERSAL, &self.traversal),
            (ATTR_VERSION, &self.version),
        ] {
            if let Some(v) = v {
                out.push((k, AttrValue::Text(v.clone())));
            }
        }
        if let Some(v) = self.spp {
            out.push((ATTR_SPP, int(v)));
        }
        if let Some(v) = self.batches {
            out.push((ATTR_BATCHES, int(v)));
        }
        out
    }

    /// Adds [`Self::attributes`] to `attributes`, replacing values of the same names.
    pub fn write_to(&self, attributes: &mut BTreeMap<String, AttrValue>) {
        for (k, v) in self.attributes() {
            attributes.insert(k.to_string(), v);
        }
    }

    /// The record in a `width`×`height` file's attributes; `path` names the file in errors.
    /// Integers are read from an `int` or from a decimal `string` (stream files of earlier
    /// versions wrote `cvtrace.rrDepth` as text); a value that is neither, or out of range, is
    /// an error naming the file and the attribute. A missing traversal reads as
    /// [`LEGACY_TRAVERSAL`].
    pub fn from_attributes(
        width: usize,
        height: usize,
        attrs: &BTreeMap<String, AttrValue>,
        path: &Path,
    ) -> Result<Provenance, StreamError> {
        let size = |v: usize, what: &str| {
            u32::try_from(v).map_err(|_| StreamError::invalid(path, format!("its {what} {v} is more than a render records")))
        };
        let text = |k: &str| attrs.get(k).map(AttrValue::as_text);
        Ok(Provenance {
            width: size(width, "width")?,
            height: size(height, "height")?,
            seed: integer(attrs, ATTR_SEED, path)?,
            max_depth: integer(attrs, ATTR_MAX_DEPTH, path)?,
            rr_depth: integer(attrs, ATTR_RR_DEPTH, path)?,
            scene_hash: text(ATTR_SCENE_HASH),
            camera: text(ATTR_CAMERA),
            traversal: Some(text(ATTR_TRAVERSAL).unwrap_or_else(|| LEGACY_TRAVERSAL.to_string())),
            spp: integer(attrs, ATTR_SPP, path)?,
            batches: integer(attrs, ATTR_BATCHES, path)?,
            version: text(ATTR_VERSION),
        })
    }

    /// The record of a file already read.
    pub fn from_exr(ch: &ExrChannels, path: &Path) -> Result<Provenance, StreamError> {
        Provenance::from_attributes(ch.width, ch.height, &ch.attributes, path)
    }

    /// The record of the file at `path`, from its header alone (no pixels are read).
    pub fn read_header(path: &Path) -> Result<Provenance, StreamError> {
        let (width, height, attrs) = ExrChannels::read_header(path)?;
        Provenance::from_attributes(width, height, &attrs, path)
    }

    /// Fails unless the file at `other` (`what`: "reference", "PT(2n) render") estimates the
    /// same image as the one at `image`: where both record them (stream files, references and
    /// PT renders do, reconstructions do not), the scene, camera, size and path length must
    /// agree. Seed, counts and traversal may differ: they change no expectation.
    pub fn check_same_image(other: &Path, what: &str, image: &Path) -> Result<(), StreamError> {
        let (o, i) = (Provenance::read_header(other)?, Provenance::read_header(image)?);
        let mismatch: Vec<String> = i
            .differences(&o)
            .into_iter()
            .filter(|d| d.field.changes_the_image())
            .map(|d| format!("{} {} in the {what}, {} in {}", d.field.name(), d.recorded, d.now, image.display()))
            .collect();
        if mismatch.is_empty() {
            return Ok(());
        }
        Err(StreamError::invalid(other, format!("not a {what} of {} (another image: {})", image.display(), mismatch.join(", "))))
    }

    /// Fails, naming `path` and the attribute, unless every field in `fields` is recorded;
    /// `what` names the file kind ("checkpoint", "reference").
    pub fn require(&self, fields: &[Field], path: &Path, what: &str) -> Result<(), StreamError> {
        match fields.iter().find(|f| self.value(**f).is_none()) {
            Some(f) => Err(StreamError::invalid(path, format!("{what} lacks the attribute {}", f.attribute().unwrap_or("size")))),
            None => Ok(()),
        }
    }
}

/// Attribute `key` as an integer of type `T`: from an `int`, or a `string` of decimal digits.
fn integer<T>(attrs: &BTreeMap<String, AttrValue>, key: &str, path: &Path) -> Result<Option<T>, StreamError>
where
    T: TryFrom<i32> + std::str::FromStr + Bounded,
{
    let expected = T::EXPECTED;
    let bad = |v: &AttrValue| StreamError::invalid(path, format!("attribute {key} = {} is not {expected}", v.as_text()));
    match attrs.get(key) {
        None => Ok(None),
        Some(v @ AttrValue::Int(i)) => T::try_from(*i).map(Some).map_err(|_| bad(v)),
        Some(v @ AttrValue::Text(t)) => t.parse::<T>().map(Some).map_err(|_| bad(v)),
        Some(v) => Err(bad(v)),
    }
}

/// What a recorded integer must be, for the error message.
trait Bounded {
    const EXPECTED: &'static str;
}
impl Bounded for u64 {
    const EXPECTED: &'static str = "an unsigned integer";
}
impl Bounded for u32 {
    const EXPECTED: &'static str = "an unsigned integer";
}
impl Bounded for i32 {
    const EXPECTED: &'static str = "an integer";
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scene_hash_of_an_older_fingerprint_is_named_as_such() {
        let d = |recorded: &str, now: &str| {
            Difference { field: Field::SceneHash, recorded: recorded.into(), now: now.into() }.describe("in the file")
        };
        let old = d("65a69bf6f120960e", "fp3:abcde11df24238af");
        assert!(old.contains("unversioned scene fingerprint") && old.contains("fp3") && old.contains("re-render"), "{old}");
        let older = d("fp2:65a69bf6f120960e", "fp3:abcde11df24238af");
        assert!(older.contains("an older (fp2)"), "{older}");
        // Two hashes of one version differ because the scenes do: no excuse offered.
        assert_eq!(d("fp3:1", "fp3:2"), "scene hash fp3:1 (in the file) vs fp3:2 (now)");
    }

    fn record() -> Provenance {
        Provenance {
            width: 32,
            height: 24,
            seed: Some(1 << 40),
            max_depth: Some(-1),
            rr_depth: Some(5),
            scene_hash: Some("0123456789abcdef".into()),
            camera: Some("eye [0, 0, 1] target [0, 0, 0] up [0, 1, 0] vfov 40".into()),
            traversal: Some("robust".into()),
            spp: Some(16),
            batches: Some(4),
            version: Some("0.1.0".into()),
        }
    }

    fn attrs_of(p: &Provenance) -> BTreeMap<String, AttrValue> {
        let mut a = BTreeMap::new();
        p.write_to(&mut a);
        a
    }

    #[test]
    fn every_field_has_one_attribute_type_and_round_trips() {
        let p = record();
        let a = attrs_of(&p);
        assert_eq!(a[ATTR_RR_DEPTH], AttrValue::Int(5));
        assert_eq!(a[ATTR_MAX_DEPTH], AttrValue::Int(-1));
        assert_eq!(a[ATTR_SPP], AttrValue::Int(16));
        assert_eq!(a[ATTR_BATCHES], AttrValue::Int(4));
        assert_eq!(a[ATTR_SEED], AttrValue::Text((1u64 << 40).to_string()));
        assert_eq!(a[ATTR_TRAVERSAL], AttrValue::Text("robust".into()));
        let names: Vec<&str> = p.without_counts().fields().into_iter().map(|(k, _)| k).collect();
        assert_eq!(names, ["size", "seed", "max depth", "rr depth", "scene hash", "camera", "traversal"]);
        assert_eq!(p.fields()[0], ("size", "32x24".to_string()));
        assert_eq!(Provenance::from_attributes(32, 24, &a, Path::new("f.exr")).unwrap(), p);
    }

    #[test]
    fn the_text_spelling_of_integers_is_read_too() {
        // Stream files of earlier versions wrote cvtrace.rrDepth as a string.
        let mut a = attrs_of(&record());
        a.insert(ATTR_RR_DEPTH.into(), AttrValue::Text("3".into()));
        assert_eq!(Provenance::from_attributes(32, 24, &a, Path::new("f.exr")).unwrap().rr_depth, Some(3));
        for bad in [AttrValue::Text("three".into()), AttrValue::Int(-2), AttrValue::Float(3.0)] {
            a.insert(ATTR_RR_DEPTH.into(), bad);
            let e = Provenance::from_attributes(32, 24, &a, Path::new("f.exr")).unwrap_err().to_string();
            assert!(e.contains("f.exr") && e.contains("cvtrace.rrDepth") && e.contains("not an unsigned integer"), "{e}");
        }
    }

    #[test]
    fn differences_name_the_fields_and_skip_unrecorded_values() {
        let now = record();
        assert!(now.differences(&now).is_empty());
        let recorded = Provenance { seed: Some(3), rr_depth: Some(4), camera: None, spp: Some(8), ..record() };
        let d = now.differences(&recorded);
        assert_eq!(d.iter().map(|d| d.field).collect::<Vec<_>>(), [Field::Seed, Field::RrDepth, Field::Spp]);
        assert_eq!(d[1].describe("in the file"), "rr depth 4 (in the file) vs 5 (now)");
        assert_eq!(describe_all(&d[..1], "checkpoint"), format!("seed 3 (checkpoint) vs {} (now)", 1u64 << 40));
        // Counts left out on either side are not compared.
        assert_eq!(now.without_counts().differences(&recorded).len(), 2);
        let size = Provenance { width: 8, ..record() };
        assert_eq!(now.differences(&size)[0].describe("reference"), "size 8x24 (reference) vs 32x24 (now)");
        assert!(Field::Size.changes_the_image() && !Field::Seed.changes_the_image() && !Field::Traversal.changes_the_image());
    }

    #[test]
    fn a_file_without_provenance_reads_as_unrecorded_and_robust() {
        let p = Provenance::from_attributes(32, 24, &BTreeMap::new(), Path::new("other.exr")).unwrap();
        assert_eq!(p, Provenance { width: 32, height: 24, traversal: Some(LEGACY_TRAVERSAL.into()), ..Default::default() });
        let e = p.require(&[Field::Seed], Path::new("other.exr"), "checkpoint").unwrap_err().to_string();
        assert_eq!(e, "other.exr: checkpoint lacks the attribute cvtrace.seed");
        assert!(record().differences(&p).is_empty());
    }
}
