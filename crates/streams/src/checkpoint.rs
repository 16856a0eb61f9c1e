//! The file forms of a progressive reference's state: the checkpoint saved after every pass
//! (exact running sums, so a resumed reference is bit-identical to one rendered at once) and
//! the finished reference that `--extend` continues (means only, so to f32 rounding).
//! docs/stream-format.md ("Reference checkpoints") describes the format.
use crate::error::{StreamError, SumsError};
use crate::exact;
use crate::exr_io::{take_rgb, AttrValue, ExrChannels};
use crate::provenance::{describe_all, Field, Provenance};
use crate::reference::{ReferenceAccum, ReferenceSettings};
use std::path::{Path, PathBuf};

/// Why a saved reference state cannot be continued.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error(transparent)]
    File(#[from] StreamError),
    #[error(transparent)]
    Sums(#[from] SumsError),
    /// A checkpoint that cannot be continued (the message names the file and why).
    #[error("{0}; delete it to start the reference over")]
    Unusable(String),
}

/// The attribute that tells a checkpoint from a finished reference, and the one layout this
/// reader knows: another value is another layout of the sums.
pub const KIND_ATTR: &str = "cvtrace.checkpoint";
pub const KIND: &str = "reference-v2";
/// Samples per pixel in the sums so far (EXR `int`).
pub const ATTR_SAMPLES_DONE: &str = "cvtrace.samplesDone";
const ATTR_NON_FINITE: &str = "cvtrace.nonFiniteSamples";
/// The version whose samples a checkpoint or reference may be continued with (every cvtrace
/// crate has the workspace's version).
const VERSION: &str = env!("CARGO_PKG_VERSION");

/// `sum.R.w0` … `sum.B.w7`: piece `piece` (bits `16·piece` to `16·piece + 15`) of the exact sum
/// of colour channel `c` ([`crate::exact`]); R, G, B hold the mean so far for viewing.
pub fn sum_channel(c: usize, piece: usize) -> String {
    exact::piece_channel(&format!("sum.{}", ["R", "G", "B"][c]), piece)
}

/// `cbox.ref.exr` → `cbox.ref.checkpoint.exr` (other names get `.checkpoint.exr` appended).
pub fn checkpoint_path(output: &Path) -> PathBuf {
    let name = output.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let stem = name.strip_suffix(".exr").unwrap_or(&name);
    output.with_file_name(format!("{stem}.checkpoint.exr"))
}

/// Writes `accum` to `path` atomically, recording `provenance` without its counts (the
/// progress is `cvtrace.samplesDone`).
pub fn save(path: &Path, accum: &ReferenceAccum, provenance: &Provenance) -> Result<(), StreamError> {
    let (w, h) = (accum.width as usize, accum.height as usize);
    let mut ch = ExrChannels::new(w, h);
    let mean = accum.mean();
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        ch.insert(*name, mean.channel(c));
    }
    exact::insert_sums3(&mut ch, "sum.", ["R", "G", "B"], &accum.sum);
    provenance.without_counts().write_to(&mut ch.attributes);
    ch.attributes.insert(KIND_ATTR.into(), AttrValue::Text(KIND.into()));
    ch.attributes.insert(ATTR_SAMPLES_DONE.into(), AttrValue::Int(accum.samples_done as i32));
    ch.attributes.insert(ATTR_NON_FINITE.into(), AttrValue::Text(accum.non_finite_samples.to_string()));
    ch.write(path, true)
}

/// The accumulator saved at `path` for the render `planned` with settings `s`; `None` if there
/// is no checkpoint. A checkpoint of another render (any difference in `planned`'s fields but
/// the counts), of another cvtrace version, or one that does not read is an error that says
/// to delete it.
pub fn load(path: &Path, planned: &Provenance, s: &ReferenceSettings) -> Result<Option<ReferenceAccum>, CheckpointError> {
    if !path.exists() {
        return Ok(None);
    }
    // Whatever is wrong with it, the way out is the same.
    read(path, planned, s).map(Some).map_err(|e| CheckpointError::Unusable(e.to_string()))
}

fn read(path: &Path, planned: &Provenance, s: &ReferenceSettings) -> Result<ReferenceAccum, StreamError> {
    let invalid = |m: String| StreamError::invalid(path, m);
    let mut ch = ExrChannels::read(path)?;
    if ch.attr(KIND_ATTR).map(AttrValue::as_text).as_deref() != Some(KIND) {
        return Err(invalid(format!("not a cvtrace {KIND} checkpoint")));
    }
    let saved = Provenance::from_exr(&ch, path)?;
    check_version(&saved, path, "checkpoint")?;
    saved.require(&[Field::Seed, Field::MaxDepth, Field::RrDepth, Field::SceneHash, Field::Camera], path, "checkpoint")?;
    let diff = planned.without_counts().differences(&saved);
    if !diff.is_empty() {
        return Err(invalid(format!(
            "checkpoint of a different render ({}); render with its settings to resume it",
            describe_all(&diff, "checkpoint")
        )));
    }
    let samples_done = match ch.attr(ATTR_SAMPLES_DONE) {
        Some(AttrValue::Int(n)) if *n >= 0 => *n as u32,
        _ => return Err(invalid(format!("checkpoint lacks a valid {ATTR_SAMPLES_DONE}"))),
    };
    let non_finite_samples = ch.attr(ATTR_NON_FINITE).and_then(|v| v.as_text().parse().ok()).unwrap_or(0);
    let sum = exact::take_sums3(&mut ch, path, "sum.", ["R", "G", "B"])?;
    Ok(ReferenceAccum { sum, samples_done, non_finite_samples, ..ReferenceAccum::new(s) })
}

/// The accumulator of the finished reference at `path`, to be extended to `s.spp` samples: its
/// record must match `planned` (counts aside) and it must hold fewer samples. A reference that
/// does not record its scene hash or camera is trusted, with a warning.
pub fn load_finished(path: &Path, planned: &Provenance, s: &ReferenceSettings) -> Result<ReferenceAccum, CheckpointError> {
    let invalid = |m: String| CheckpointError::from(StreamError::invalid(path, m));
    let mut ch = ExrChannels::read(path)?;
    if ch.attr(KIND_ATTR).is_some() {
        return Err(invalid("this is a checkpoint, not a finished reference".into()));
    }
    // What the file is matters before how it was rendered: its seed or depth are beside the point.
    if ch.attr(crate::parts::KIND_ATTR).is_some() {
        return Err(invalid(
            "--extend: this is a part of a render (`render --part`), not a finished reference; merge the parts first".into(),
        ));
    }
    if ch.channels.contains_key("pt.R") || ch.channels.contains_key("crn.R") {
        return Err(invalid(
            "--extend: this is a PT/CRN stream file, not a reference; --extend continues a reference that `render --reference` wrote"
                .into(),
        ));
    }
    let saved = Provenance::from_exr(&ch, path)?;
    check_version(&saved, path, "reference")?;
    saved.require(&[Field::Seed, Field::MaxDepth, Field::RrDepth], path, "reference")?;
    let diff = planned.without_counts().differences(&saved);
    if !diff.is_empty() {
        return Err(invalid(format!("--extend: the reference is of a different render ({})", describe_all(&diff, "reference"))));
    }
    if saved.scene_hash.is_none() || saved.camera.is_none() {
        tracing::warn!(
            "{}: written before references recorded their scene hash and camera; trusting that the scene is unchanged",
            path.display()
        );
    }
    let done = match ch.attr(Field::Spp.attribute().unwrap_or_default()) {
        Some(AttrValue::Int(n)) if *n > 0 => *n as u32,
        _ => return Err(invalid("reference lacks a valid cvtrace.spp".into())),
    };
    if done >= s.spp {
        return Err(invalid(format!("--extend: the reference already holds {done} spp; ask for more with --spp (now {})", s.spp)));
    }
    let mean = take_rgb(&mut ch, path, "")?;
    let mut accum = ReferenceAccum::from_mean(s, &mean, done)?;
    accum.non_finite_samples = ch.attr(ATTR_NON_FINITE).and_then(|v| v.as_text().parse().ok()).unwrap_or(0);
    Ok(accum)
}

/// Another cvtrace version may draw other samples for the same settings: its sums are not
/// continued.
fn check_version(saved: &Provenance, path: &Path, what: &str) -> Result<(), StreamError> {
    let version =
        saved.version.as_deref().ok_or_else(|| StreamError::invalid(path, format!("{what} lacks the attribute cvtrace.version")))?;
    if version != VERSION {
        let advice = if what == "reference" { "render a new reference" } else { "delete it to start over" };
        return Err(StreamError::invalid(
            path,
            format!("{what} written by cvtrace {version}, this is {VERSION}, whose samples may differ; {advice}"),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Image;

    #[test]
    fn checkpoint_sits_next_to_the_output() {
        assert_eq!(checkpoint_path(Path::new("out/cbox.ref.exr")), Path::new("out/cbox.ref.checkpoint.exr"));
        assert_eq!(checkpoint_path(Path::new("ref")), Path::new("ref.checkpoint.exr"));
    }

    fn settings() -> ReferenceSettings {
        ReferenceSettings { width: 3, height: 2, spp: 8, seed: 9, max_depth: 4, rr_depth: 5 }
    }

    fn planned(s: &ReferenceSettings) -> Provenance {
        Provenance {
            width: s.width,
            height: s.height,
            seed: Some(s.seed),
            max_depth: Some(s.max_depth),
            rr_depth: Some(s.rr_depth),
            scene_hash: Some("00000000000000ab".into()),
            camera: Some("cam".into()),
            traversal: Some("robust".into()),
            spp: Some(s.spp),
            batches: None,
            version: Some(VERSION.into()),
        }
    }

    #[test]
    fn sums_round_trip_exactly_and_another_render_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.checkpoint.exr");
        let s = settings();
        let mut accum = ReferenceAccum::new(&s);
        for (i, v) in accum.sum.iter_mut().enumerate() {
            *v = [i as i128 * 12345, -(1 << 100), i128::MAX / (i as i128 + 1)];
        }
        accum.samples_done = 3;
        accum.non_finite_samples = 2;
        save(&p, &accum, &planned(&s)).unwrap();
        let ch = ExrChannels::read(&p).unwrap();
        assert_eq!(ch.attr(KIND_ATTR), Some(&AttrValue::Text(KIND.into())));
        assert_eq!(ch.attr("cvtrace.rrDepth"), Some(&AttrValue::Int(5)));
        assert_eq!(ch.attr("cvtrace.spp"), None, "a checkpoint's progress is samplesDone");
        assert_eq!(load(&p, &planned(&s), &s).unwrap(), Some(accum));
        assert_eq!(load(&dir.path().join("none.exr"), &planned(&s), &s).unwrap(), None);

        let other = Provenance { seed: Some(10), ..planned(&s) };
        let e = load(&p, &other, &s).unwrap_err().to_string();
        assert!(
            e.contains("r.checkpoint.exr")
                && e.contains("seed 9 (checkpoint) vs 10 (now)")
                && e.ends_with("delete it to start the reference over"),
            "{e}"
        );
    }

    #[test]
    fn a_finished_reference_extends_only_to_more_samples() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.exr");
        let s = settings();
        let mut attrs = Provenance { spp: Some(4), ..planned(&s) }.attributes();
        attrs.retain(|(k, _)| *k != "cvtrace.sceneHash");
        crate::exr_io::write_rgb(&p, &Image::from_fn(3, 2, |x, _| [x as f32, 1.0, 2.0]), &attrs, false).unwrap();
        let a = load_finished(&p, &planned(&s), &s).unwrap();
        assert_eq!((a.samples_done, a.sum[1][0]), (4, exact::fixed(4.0)));
        let few = ReferenceSettings { spp: 4, ..s };
        let e = load_finished(&p, &planned(&few), &few).unwrap_err().to_string();
        assert!(e.contains("already holds 4 spp"), "{e}");
        let e = load_finished(&p, &Provenance { max_depth: Some(2), ..planned(&s) }, &s).unwrap_err().to_string();
        assert!(e.contains("r.exr: --extend: the reference is of a different render (max depth 4 (reference) vs 2 (now))"), "{e}");
    }
}
