//! `cvtrace compare`: error of a handful of EXR images against one reference, one seed each:
//! relMSE and its companions, and HDR-FLIP (see `flip`).
//!
//! Method names come from each file's `cvtrace.method` header attribute (written by
//! `cvtrace reconstruct`), else from the file stem; `cvtrace.seconds` becomes the
//! reconstruction time and `cvtrace.spp` the sample count when present.
use crate::flip::{FlipAccumulator, FlipReference};
use crate::metrics::Reference;
use crate::results::{MethodResult, ReferenceInfo, SceneResult, StageTimes};
use crate::stats::SeedAccumulator;
use crate::EvalError;
use cvtrace_streams::exr_io::{take_rgb, AttrValue, ExrChannels};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Reads the reference and every image; errors name the file at fault (unreadable EXR,
/// missing R/G/B, non-finite values, size different from the reference, a reference of another
/// scene, camera or path length than an image records).
pub fn compare_files(reference: &Path, images: &[PathBuf]) -> Result<SceneResult, EvalError> {
    if images.is_empty() {
        return Err(EvalError::invalid("compare", "no images to compare"));
    }
    // An image of another scene, camera or path length is no estimate of this reference.
    for path in images {
        cvtrace_streams::Provenance::check_same_image(reference, "reference", path)?;
    }
    let reference_img = Reference::read_exr(reference)?;
    let flip_reference = FlipReference::new(&reference_img.image, reference_img.label.clone())?;
    let mut names = BTreeSet::new();
    let mut methods = Vec::new();
    // The samples per stream of the stream files the images were made from, as recorded.
    let mut stream_spps = BTreeSet::new();
    for path in images {
        let label = path.display().to_string();
        let mut ch = ExrChannels::read(path)?;
        let img = take_rgb(&mut ch, path, "")?;
        let mut acc = SeedAccumulator::new(&reference_img, label.clone());
        acc.add_labelled(&img, &label)?;
        let stats = acc.finish()?;
        let mut flip = FlipAccumulator::new(&flip_reference);
        flip.add(&img, &label)?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| label.clone());
        let base = match ch.attr("cvtrace.method") {
            Some(AttrValue::Text(m)) if !m.trim().is_empty() => m.trim().to_string(),
            _ => stem.clone(),
        };
        let mut name = base.clone();
        let mut k = 2;
        while !names.insert(name.clone()) {
            name = format!("{base}-{k}");
            k += 1;
        }
        let spp = match ch.attr("cvtrace.spp") {
            Some(AttrValue::Int(v)) if *v > 0 => *v as u32,
            _ => 0,
        };
        stream_spps.insert(match ch.attr("cvtrace.streamSpp") {
            Some(AttrValue::Int(v)) if *v > 0 => *v as u32,
            _ => 0,
        });
        // Show the method when the header named one the file name does not.
        let shown = if base == stem { label.clone() } else { format!("{base} ({label})") };
        let mut m = MethodResult::from_stats(&name, &shown, spp, &stats);
        if let Some(f) = flip.finish() {
            m.set_flip(&f);
        }
        if let Some(AttrValue::Float(s)) = ch.attr("cvtrace.seconds") {
            if s.is_finite() && *s >= 0.0 {
                m.time_seconds = StageTimes { render: 0.0, reconstruct: *s as f64 };
            }
        }
        methods.push(m);
    }
    let name = reference.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "scene".into());
    Ok(SceneResult {
        name: name.trim_end_matches(".ref").to_string(),
        width: reference_img.width(),
        height: reference_img.height(),
        // One value when every image records the same; 0 (unknown) otherwise.
        spp_per_stream: match stream_spps.iter().collect::<Vec<_>>()[..] {
            [&n] => n,
            _ => 0,
        },
        seeds: 1,
        reference: ReferenceInfo { path: ReferenceInfo::path_of(reference), spp: None, image: None, noise: None, values: None },
        methods,
        convergence: Vec::new(),
        error_map_scale: None,
        difference_scale: None,
        flip: Some(flip_reference.settings()),
        warnings: reference_img.unusable_warning().into_iter().collect(),
        headline: crate::results::paper_headline(),
        render: Vec::new(),
    })
}

/// The terminal table of `compare`: one image per row, each scored once, so only what a single
/// image has (samples, relMSE, MSE, HDR-FLIP, the reconstruction's seconds where its file
/// records them); the study's columns over seeds would be empty. Warnings are the caller's to
/// show.
pub fn compare_table(scene: &SceneResult) -> String {
    use crate::table::{aligned, fmt_num, fmt_seconds, scene_title};
    let flip = scene.methods.iter().any(|m| m.flip_mean.is_some());
    let seconds = scene.methods.iter().any(|m| m.time_seconds.reconstruct > 0.0);
    let mut header = vec!["method", "spp", "relMSE", "MSE"];
    header.extend(flip.then_some("FLIP"));
    header.extend(seconds.then_some("recon s"));
    let rows: Vec<Vec<String>> = scene
        .methods
        .iter()
        .map(|m| {
            let mut row = vec![
                m.label.clone(),
                if m.spp_total > 0 { m.spp_total.to_string() } else { "?".into() },
                fmt_num(m.relmse_mean),
                fmt_num(m.mse_mean),
            ];
            row.extend(flip.then(|| m.flip_mean.map(fmt_num).unwrap_or_else(|| "–".into())));
            row.extend(seconds.then(|| fmt_seconds(m.time_seconds.reconstruct)));
            row
        })
        .collect();
    format!("{}\n\n{}", scene_title(scene), aligned(&header, &rows))
}

#[cfg(test)]
mod tests {
    use super::*;
    use cvtrace_streams::exr_io::write_rgb;
    use cvtrace_streams::Image;

    #[test]
    fn compares_files_and_names_methods_from_headers() {
        let dir = tempfile::tempdir().unwrap();
        let r = Image::from_fn(6, 4, |x, y| [x as f32 * 0.1, y as f32 * 0.2, 0.5]);
        let ref_path = dir.path().join("cbox.ref.exr");
        write_rgb(&ref_path, &r, &[], false).unwrap();
        let mut off = r.clone();
        off.pixels.iter_mut().for_each(|p| p[0] += 0.1);
        let a = dir.path().join("a.exr");
        write_rgb(&a, &off, &[("cvtrace.method", AttrValue::Text("ours".into())), ("cvtrace.seconds", AttrValue::Float(1.5))], false)
            .unwrap();
        let b = dir.path().join("plain.exr");
        write_rgb(&b, &r, &[], false).unwrap();
        let scene = compare_files(&ref_path, &[a, b]).unwrap();
        assert_eq!(scene.name, "cbox");
        let ours = scene.method("ours").unwrap();
        let expected = crate::metrics::rel_mse(&off, &r).unwrap();
        assert!((ours.relmse_mean - expected).abs() < 1e-12 * expected);
        assert_eq!(ours.time_seconds.reconstruct, 1.5);
        assert_eq!(scene.method("plain").unwrap().relmse_mean, 0.0);
        // HDR-FLIP beside relMSE: none for the reference itself, some for the offset image.
        assert_eq!(scene.method("plain").unwrap().flip_mean, Some(0.0));
        let flip = crate::flip::hdr_flip(&r, &off).unwrap().mean;
        assert!(flip > 0.0 && ours.flip_mean == Some(flip), "{:?} vs {flip}", ours.flip_mean);
        assert!(ours.flip_se.is_none() && ours.flip_per_seed == [flip]);
        assert_eq!(scene.flip.as_ref().unwrap().ppd, crate::flip::DEFAULT_PPD);
        assert!(ours.relmse_se.is_none() && ours.bias2.is_none());
        crate::results::StudyResults::new(vec![scene.clone()]).validate().unwrap();
        assert!(crate::table::terminal_table(&scene).contains("ours"));
        // Only the columns a single image has: no standard errors, bias, variance or render time.
        let table = compare_table(&scene);
        let header = table.lines().find(|l| l.starts_with("method")).unwrap();
        assert!(header.contains("relMSE") && header.contains("FLIP") && header.contains("recon s"), "{table}");
        assert!(!header.contains("± se") && !header.contains("bias²") && !header.contains("render s"), "{table}");
        // Neither file records the samples per stream.
        assert_eq!(scene.spp_per_stream, 0);
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);

        // A black reference cannot rank anything, and one with negative pixels is not radiance.
        for (image, needle) in [(Image::new(6, 4), "black everywhere"), (off.clone(), "")] {
            let mut image = image;
            if needle.is_empty() {
                image.pixels[3][1] = -0.5;
            }
            write_rgb(&ref_path, &image, &[], true).unwrap();
            let scene = compare_files(&ref_path, &[dir.path().join("plain.exr")]).unwrap();
            let expected = if needle.is_empty() { "1 reference pixels are negative" } else { needle };
            assert!(scene.warnings.iter().any(|w| w.contains("cbox.ref.exr") && w.contains(expected)), "{:?}", scene.warnings);
            assert!(crate::table::terminal_table(&scene).contains(&format!("warning: {}", scene.warnings[0])));
        }
    }

    #[test]
    fn bad_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let ref_path = dir.path().join("ref.exr");
        write_rgb(&ref_path, &Image::new(4, 4), &[], false).unwrap();
        let small = dir.path().join("small.exr");
        write_rgb(&small, &Image::new(4, 3), &[], false).unwrap();
        let err = compare_files(&ref_path, &[small]).unwrap_err().to_string();
        assert!(err.contains("small.exr") && err.contains("ref.exr") && err.contains("4x3"), "{err}");
        let junk = dir.path().join("junk.exr");
        std::fs::write(&junk, b"junk").unwrap();
        assert!(compare_files(&ref_path, &[junk]).unwrap_err().to_string().contains("junk.exr"));
        assert!(compare_files(&ref_path, &[]).is_err());
    }
}
