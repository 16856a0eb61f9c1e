//! The study driver on the synthetic source: no renderer, every built-in estimator, the
//! results and images a report reads.
use cvtrace_eval::results::ReferenceInfo;
use cvtrace_eval::Reference;
use cvtrace_reconstruct::{Overrides, Registry};
use cvtrace_study::{columns, headline, SceneInfo, Study, StudyError, SyntheticSource};

#[test]
fn a_study_of_the_synthetic_scene_scores_every_estimator() {
    let dir = tempfile::tempdir().unwrap();
    let registry = Registry::builtin();
    let cols = columns(&registry, &Overrides::default(), true).unwrap();
    let heads = headline(&["ours/iduw".into(), "ours/pt2n".into()], &cols).unwrap();
    let study = Study { columns: &cols, spps: vec![8, 16], seeds: 3, first_seed: 11, batches: 8, headline: heads };
    study.check_needs().unwrap();
    let mut source = SyntheticSource::new(40, 32);
    let reference = Reference::new(source.reference(), "exact".to_string()).unwrap();
    let info = SceneInfo {
        name: "soft shadow".into(),
        reference: ReferenceInfo { path: "synthetic".into(), spp: None, image: None, noise: None, values: None },
        render: vec![("scene".into(), "synthetic".into())],
    };
    let results = study.run(&mut source, &reference, info, dir.path()).unwrap();
    let scene = &results.scenes[0];
    for key in ["pt", "crn", "average", "iduw", "cv", "ours", "pt2n", "ours-oracle", "ours-gbuffer"] {
        let m = scene.method(key).unwrap_or_else(|| panic!("{key} missing"));
        assert_eq!(m.relmse_per_seed.len(), 3, "{key}");
        assert!(dir.path().join(m.image.as_ref().unwrap()).is_file() && dir.path().join(m.error_map.as_ref().unwrap()).is_file());
        // HDR-FLIP at the last spp, over the same seeds, with its map.
        assert_eq!(m.flip_per_seed.len(), 3, "{key}");
        assert!(m.flip_mean.is_some_and(|f| f > 0.0 && f < 1.0) && m.flip_se.is_some(), "{key}: {:?}", m.flip_mean);
        assert!(dir.path().join(m.flip_map.as_ref().unwrap()).is_file(), "{key}");
    }
    assert!(scene.flip.as_ref().is_some_and(|f| f.num_exposures >= 2));
    // FLIP agrees with relMSE that PT(2n) beats PT(n).
    let flip = |k: &str| scene.method(k).unwrap().flip_mean.unwrap();
    assert!(flip("pt2n") < flip("pt"), "{} vs {}", flip("pt2n"), flip("pt"));
    // Equal samples: PT(2n) about halves PT(n)'s error, and ours beats PT(2n) on this scene
    // (its CRN noise is smooth), by far more than the seed noise at 3 seeds.
    let rel = |k: &str| scene.method(k).unwrap().relmse_mean;
    assert!((rel("pt2n") / rel("pt") - 0.5).abs() < 0.15, "{} vs {}", rel("pt2n"), rel("pt"));
    assert!(rel("ours") < 0.7 * rel("pt2n"), "ours {} vs PT(2n) {}", rel("ours"), rel("pt2n"));
    assert_eq!(scene.convergence.iter().filter(|p| p.method == "ours").count(), 2);
    assert_eq!(scene.ratios().len(), 2);
    assert!(dir.path().join("results.json").is_file() && dir.path().join("results.csv").is_file());
}

#[test]
fn needs_no_column_can_meet_fail_before_any_image() {
    let registry = Registry::builtin();
    let cols = columns(&registry, &Overrides::default(), false).unwrap();
    // IDUW forms four sub-buffers: 6 batches cannot do.
    let study = Study { columns: &cols, spps: vec![12], seeds: 1, first_seed: 1, batches: 6, headline: vec![] };
    let e = study.check_needs().unwrap_err();
    assert!(matches!(e, StudyError::Needs { spp: 12, batches: 6, .. }) && e.to_string().contains("multiple of 4"), "{e}");
    let e = headline(&["ours/nothing".into()], &cols).unwrap_err().to_string();
    assert!(e.contains("nothing") && e.contains("pt2n"), "{e}");
}
