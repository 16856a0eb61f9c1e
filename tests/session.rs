//! The render session: one scene load and one BVH build for every render of a study, outputs
//! that record their provenance with one attribute type per field, and files written before
//! that unification (stream files with a text `cvtrace.rrDepth`, the committed references)
//! still accepted.
mod common;

use common::{cvtrace, ok, scene, stderr, SMALL};
use cvtrace_session::{Job, NoProgress, ReferenceJob, RenderSession, SessionOptions, StreamJob, View};
use cvtrace_streams::exr_io::{AttrValue, ExrChannels};
use cvtrace_streams::Provenance;
use std::path::Path;

/// The log line the session writes for every BVH it builds.
const BUILT: &str = "built the Embree BVH";

fn builds(log: &str) -> usize {
    log.lines().filter(|l| l.contains(BUILT)).count()
}

#[test]
fn a_study_of_two_seeds_builds_the_bvh_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene();
    let study = [
        &["--log", "info", "study", s.to_str().unwrap(), "--spp", "4,8", "--seeds", "2"][..],
        &["--batches", "4", "--reference", "ref.exr", "--reference-spp", "16", "-o", "st"],
        SMALL,
    ]
    .concat();
    let out = cvtrace(d, &study);
    ok(&out);
    let log = stderr(&out);
    // The reference, then per spp value and seed a stream file and a PT(2n) render: nine
    // renders of one scene, one BVH.
    let renders = log.lines().filter(|l| l.contains("rendering ") && l.contains(" threads")).count();
    assert_eq!(renders, 9, "{log}");
    assert_eq!(builds(&log), 1, "one BVH for every render of the study:\n{log}");

    // A stream file from before the provenance was typed records rrDepth as text: still
    // reused, and a resumed study that renders nothing builds no BVH.
    let old = d.join("st/spp00008/seed-001.streams.exr");
    let mut ch = ExrChannels::read(&old).unwrap();
    assert_eq!(ch.attr("cvtrace.rrDepth"), Some(&AttrValue::Int(5)));
    ch.attributes.insert("cvtrace.rrDepth".into(), AttrValue::Text("5".into()));
    ch.write(&old, true).unwrap();
    let again = cvtrace(d, &study);
    ok(&again);
    let log = stderr(&again);
    assert!(log.contains(&format!("reusing {}", Path::new("st/spp00008/seed-001.streams.exr").display())), "{log}");
    assert_eq!(builds(&log), 0, "{log}");
    // The text spelling is still compared: another rr depth is refused.
    ch.attributes.insert("cvtrace.rrDepth".into(), AttrValue::Text("3".into()));
    ch.write(&old, true).unwrap();
    let refused = cvtrace(d, &study);
    assert!(!refused.status.success() && stderr(&refused).contains("rr depth 3 (in the file) vs 5 (now)"), "{}", stderr(&refused));
}

#[test]
fn one_session_renders_streams_and_references_on_one_bvh() {
    let dir = tempfile::tempdir().unwrap();
    let session = RenderSession::new(&scene(), &SessionOptions::default()).unwrap();
    assert_eq!(session.bvh_builds(), 0, "the BVH is built at the first render");
    let view = View { width: Some(16), height: Some(12), max_depth: Some(4), rr_depth: None };
    let stream = |seed: u64| {
        let output = dir.path().join(format!("s{seed}.streams.exr"));
        Job::Streams(StreamJob { output, view, spp: Some(4), batches: 2, seed, overwrite: false, part: None })
    };
    let reference = Job::Reference(ReferenceJob::replacing(dir.path().join("r.exr"), view, 6, 9));
    for job in [stream(1), stream(2), reference.clone()] {
        session.render(&job, &NoProgress).unwrap();
        // Each file records exactly what its plan says, rrDepth as an int in both kinds.
        let recorded = Provenance::read_header(job.output()).unwrap();
        assert_eq!(session.plan(&job).unwrap().provenance, recorded);
        let ch = ExrChannels::read(job.output()).unwrap();
        assert_eq!(ch.attr("cvtrace.rrDepth"), Some(&AttrValue::Int(5)), "{}", job.output().display());
    }
    assert_eq!(session.bvh_builds(), 1);
    // A job for another seed differs from the file in exactly that.
    let Job::Reference(mut other) = reference else { unreachable!() };
    other.seed = 10;
    let d =
        session.plan(&Job::Reference(other)).unwrap().provenance.differences(&Provenance::read_header(&dir.path().join("r.exr")).unwrap());
    assert_eq!(d.len(), 1, "{d:?}");
    assert_eq!(d[0].describe("in the file"), "seed 9 (in the file) vs 10 (now)");
}

#[test]
fn the_committed_references_are_accepted_by_the_study_and_by_extend() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // cornell-box's reference records no scene hash or camera; door-ajar's records both.
    for name in ["cornell-box", "door-ajar"] {
        let gltf = root.join(format!("scenes/{name}/scene.gltf"));
        let committed = root.join(format!("scenes/{name}/scene.ref.exr"));
        let ch = ExrChannels::read(&committed).unwrap();
        let (spp, seed) = match (ch.attr("cvtrace.spp"), ch.attr("cvtrace.seed")) {
            (Some(AttrValue::Int(n)), Some(s)) => (*n, s.as_text()),
            other => panic!("{name}: {other:?}"),
        };
        // Extending a copy by one sample per pixel checks its provenance against the scene
        // (the committed references were traced robustly, which --extend must continue).
        let copy = d.join(format!("{name}.ref.exr"));
        std::fs::copy(&committed, &copy).unwrap();
        let more = (spp + 1).to_string();
        let extend = cvtrace(
            d,
            &[
                "--log",
                "warn",
                "render",
                gltf.to_str().unwrap(),
                "--reference",
                "--traversal",
                "robust",
                "--spp",
                &more,
                "--seed",
                &seed,
                "--extend",
                "-o",
                copy.to_str().unwrap(),
            ],
        );
        ok(&extend);
        assert_eq!(ExrChannels::read(&copy).unwrap().attr("cvtrace.spp"), Some(&AttrValue::Int(spp + 1)));
        // A study at the scene's own size scores against the committed file as it is.
        let out = d.join(format!("{name}-study"));
        let study = cvtrace(
            d,
            &[
                "--log",
                "warn",
                "study",
                gltf.to_str().unwrap(),
                "--spp",
                "4",
                "--seeds",
                "1",
                "--batches",
                "4",
                "--reference",
                committed.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ],
        );
        ok(&study);
        assert!(out.join("results.json").is_file());
    }
}
