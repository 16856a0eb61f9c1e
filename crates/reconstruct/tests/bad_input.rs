//! Bad input gives clear errors that name the file, the channel and the fix.
mod common;

use common::stream_set;
use cvtrace_reconstruct::synthetic::{RenderSpec, SoftShadowScene};
use cvtrace_reconstruct::*;
use cvtrace_streams::exr_io::{read_rgb, write_rgb};
use cvtrace_streams::{Image, StreamSet};

fn set(b: usize) -> StreamSet {
    SoftShadowScene::default().render(&RenderSpec { width: 12, height: 8, spp: 2 * b as u32, batches: b, seed: 1 }).unwrap()
}

fn err(method: &str, assignments: &[&str], input: &Input) -> String {
    build(method, &Overrides::parse(assignments).unwrap()).unwrap().run(input).unwrap_err().to_string()
}

#[test]
fn batch_counts_that_do_not_fit() {
    let s6 = set(6);
    let input = Input::new(&s6).named("cbox.streams.exr", "-");
    let e = err("iduw", &[], &input);
    assert!(e.contains("cbox.streams.exr") && e.contains("multiple of 4") && e.contains("6"), "{e}");
    let s1 = set(1);
    let e = err("ours", &[], &Input::new(&s1).named("one.exr", "-"));
    assert!(e.contains("one.exr") && e.contains("at least 2") && e.contains("--batches"), "{e}");
    let mut odd = set(4);
    odd.crn.batches.pop();
    let e = err("cv", &[], &Input::new(&odd).named("odd.exr", "-"));
    assert!(e.contains("odd.exr") && e.contains("pt has 4") && e.contains("crn has 3"), "{e}");
    // Methods that only read the means do not care.
    assert!(build("average", &Overrides::default()).unwrap().run(&Input::new(&odd)).is_ok());
}

#[test]
fn non_finite_values_name_the_channel_and_pixel() {
    let mut s = set(4);
    s.pt.batches[3].pixels[2 * 12 + 5][1] = f32::NAN;
    let e = err("ours", &[], &Input::new(&s).named("nan.streams.exr", "-"));
    assert!(e.contains("nan.streams.exr") && e.contains("pt.b03.G") && e.contains("(5, 2)"), "{e}");
    // PT alone never reads batches, but it does read the mean.
    s.pt.mean.pixels[0][2] = f32::INFINITY;
    let e = err("pt", &[], &Input::new(&s).named("nan.streams.exr", "-"));
    assert!(e.contains("pt.B") && e.contains("(0, 0)"), "{e}");
}

#[test]
fn mismatched_sizes_are_named() {
    let mut s = set(4);
    s.crn.batches[1] = Image::new(11, 8);
    let e = err("ours", &[], &Input::new(&s).named("s.exr", "-"));
    assert!(e.contains("s.exr") && e.contains("crn.b01") && e.contains("11x8") && e.contains("12x8"), "{e}");
}

#[test]
fn missing_features_and_reference() {
    let mut s = set(4);
    s.features = None;
    let e = err("ours", &["ours.select=gbuffer"], &Input::new(&s).named("nofeat.exr", "-"));
    assert!(e.contains("nofeat.exr") && e.contains("albedo") && e.contains("gbuffer"), "{e}");
    let est = build("ours", &Overrides::parse(["ours.errors=oracle"]).unwrap()).unwrap();
    assert!(est.needs().reference);
    let e = est.run(&Input::new(&s)).unwrap_err().to_string();
    assert!(e.contains("oracle") && e.contains("--reference"), "{e}");
    let mut zero = set(4);
    zero.meta.spp = 0;
    let e = err("iduw", &[], &Input::new(&zero).named("nospp.exr", "-"));
    assert!(e.contains("nospp.exr") && e.contains("spp"), "{e}");
}

#[test]
fn reference_of_the_wrong_size_read_from_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cbox.ref.exr");
    write_rgb(&path, &Image::new(10, 8), &[], false).unwrap();
    let reference = read_rgb(&path).unwrap();
    let s = set(4);
    let name = path.display().to_string();
    let e = err("ours", &["ours.errors=oracle"], &Input::new(&s).with_reference(&reference).named("cbox.streams.exr", &name));
    assert!(e.contains("cbox.ref.exr") && e.contains("cbox.streams.exr") && e.contains("10x8") && e.contains("12x8"), "{e}");
}

#[test]
fn streams_read_from_a_file_are_named_in_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("six.streams.exr");
    set(6).write(&path, false).unwrap();
    let s = StreamSet::read(&path).unwrap();
    let name = path.display().to_string();
    let e = err("iduw", &[], &Input::new(&s).named(&name, "-"));
    assert!(e.contains("six.streams.exr") && e.contains("multiple of 4"), "{e}");
}

#[test]
fn absurd_options_are_refused_before_any_work() {
    let bad = |assignments: &[&str]| {
        let o = Overrides::parse(assignments).unwrap();
        Registry::builtin().check(&o).err().map(|e| e.to_string()).unwrap_or_else(|| panic!("accepted {o:?}"))
    };
    let e = bad(&["ours.k=0"]);
    assert!(e.contains("--k 0") && e.contains("ours.k"), "{e}");
    let e = bad(&["ours.k=30", "ours.search_window=5"]);
    assert!(e.contains("--k 30") && e.contains("5x5") && e.contains("--search-window"), "{e}");
    let e = bad(&["ours.k=65"]);
    assert!(e.contains("64"), "{e}");
    let e = bad(&["ours.search_window=10"]);
    assert!(e.contains("--search-window 10") && e.contains("odd"), "{e}");
    let e = bad(&["ours.ridge=-1"]);
    assert!(e.contains("--ridge -1"), "{e}");
    let e = bad(&["ours.cbf_radius=0"]);
    assert!(e.contains("cbf-radius"), "{e}");
    let e = bad(&["iduw.window=4"]);
    assert!(e.contains("--iduw-window 4"), "{e}");
    let e = bad(&["iduw.gammas="]);
    assert!(e.contains("iduw.gammas") && e.contains("at least one"), "{e}");
    // cv's `k` counts the centre as ours' does (cv uses the k − 1 neighbours).
    let e = bad(&["cv.k=122"]);
    assert!(e.contains("--k 122"), "{e}");
    let e = bad(&["cv.k=1"]);
    assert!(e.contains("--k 1 (cv.k)") && e.contains("between 2"), "{e}");
    let e = bad(&["cv.ridge=NaN"]);
    assert!(e.contains("--cv-ridge NaN"), "{e}");
    // The typed options are checked as strictly as the parameters.
    assert!(estimators::ClassicCv::new(ClassicCvOptions { neighbours: 0, ..Default::default() })
        .unwrap_err()
        .to_string()
        .contains("at least one neighbour"));
    let e = "lasso".parse::<Penalty>().unwrap_err().to_string();
    assert!(e.contains("lasso") && e.contains("avg"), "{e}");
    let e = "nearest".parse::<Selection>().unwrap_err().to_string();
    assert!(e.contains("knn, window, random, gbuffer"), "{e}");
}

#[test]
fn too_many_batches_are_refused_with_a_fix() {
    let s = stream_set(4, 4, 65, 65, |_| 1.0, |b, _| b as f64 * 1e-3, |_, i| i as f64 * 1e-3);
    let e = err("ours", &[], &Input::new(&s).named("many.exr", "-"));
    assert!(e.contains("many.exr") && e.contains("at most 64") && e.contains("merge"), "{e}");
}

#[test]
fn buffers_from_another_renderer() {
    let im = |w: usize, v: f32| Image::from_fn(w, 3, |_, _| [v; 3]);
    let set = stream_set_from_batches(vec![im(4, 1.0), im(4, 3.0)], vec![im(4, 2.0), im(4, 2.0)], 8, None).unwrap();
    assert_eq!((set.width, set.height, set.batch_count(), set.meta.spp), (4, 3, 2, 8));
    assert_eq!(set.pt.mean.get(0, 0), [2.0; 3]);
    let e = stream_set_from_batches(vec![im(4, 1.0), im(5, 1.0)], vec![im(4, 1.0), im(4, 1.0)], 8, None).unwrap_err().to_string();
    assert!(e.contains("pt.b01") && e.contains("5x3") && e.contains("4x3"), "{e}");
    let e = stream_set_from_batches(vec![im(4, 1.0)], vec![im(4, 1.0), im(4, 1.0)], 8, None).unwrap_err().to_string();
    assert!(e.contains("pt has 1") && e.contains("crn has 2"), "{e}");
    assert!(stream_set_from_batches(vec![], vec![], 8, None).is_err());
}

#[test]
fn values_too_large_for_f32_squares_are_refused_by_the_methods_that_square_them() {
    // Found by fuzzing: the Cornell box streams multiplied by 1e19 (values up to 1.7e20, all
    // finite, every stream mean the mean of its batches) gave `cv` and `ours` images 39% and
    // 17% away from the rescaled image, with no error.
    let scaled = |k: f32| {
        let mut s = set(4);
        for stream in [&mut s.pt, &mut s.crn] {
            for im in std::iter::once(&mut stream.mean).chain(stream.batches.iter_mut()) {
                im.pixels.iter_mut().flatten().for_each(|v| *v *= k);
            }
        }
        s
    };
    let big = scaled(1e19);
    let input = Input::new(&big).named("huge.streams.exr", "-");
    for m in ["cv", "ours"] {
        let e = err(m, &[], &input);
        assert!(e.contains("huge.streams.exr") && e.contains("beyond ±1e18") && e.contains("scale the image down") && e.contains(m), "{e}");
    }
    // The methods that do not square values take them.
    for m in ["pt", "crn", "average", "iduw"] {
        assert!(build(m, &Overrides::default()).unwrap().run(&input).is_ok(), "{m}");
    }
    // Below the limit the images are the rescaled ones.
    let (one, k) = (set(4), 1e12f32);
    let large = scaled(k);
    for m in ["cv", "ours"] {
        let a = build(m, &Overrides::default()).unwrap().run(&Input::new(&one)).unwrap().image;
        let b = build(m, &Overrides::default()).unwrap().run(&Input::new(&large)).unwrap().image;
        let top = a.pixels.iter().flatten().fold(0.0f32, |t, v| t.max(v.abs()));
        for (p, q) in a.pixels.iter().flatten().zip(b.pixels.iter().flatten()) {
            assert!((q / k - p).abs() <= 1e-4 * top, "{m}: {p} vs {}", q / k);
        }
    }
    // An oracle reference is held to the same limit.
    let mut reference = Image::from_fn(12, 8, |_, _| [1.0; 3]);
    reference.pixels[13][2] = -3e18;
    let s = set(4);
    let e = err("ours", &["ours.errors=oracle"], &Input::new(&s).with_reference(&reference).named("s.exr", "ref.exr"));
    assert!(e.starts_with("ref.exr") && e.contains("pixel (1, 1)") && e.contains("-3e18"), "{e}");
}

#[test]
fn a_non_finite_output_names_the_method_pixel_channel_and_largest_input() {
    let im = |v: f32| Image::from_fn(4, 3, |_, _| [v; 3]);
    let set = stream_set_from_batches(vec![im(1.0), im(-3.0)], vec![im(2.0), im(2.0)], 8, None).unwrap();
    let input = Input::new(&set).named("other.exr", "-");
    assert_eq!(input.check_output("pt", &im(1.0)), Ok(()));
    let mut out = im(1.0);
    out.pixels[4 + 2][1] = f32::NAN;
    let e = input.check_output("pt", &out).unwrap_err().to_string();
    assert!(e.starts_with("other.exr: `pt` produced a non-finite value at pixel (2, 1), channel G;") && e.contains("(largest 2e0)"), "{e}");
}
