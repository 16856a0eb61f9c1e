//! IDUW's public input layout: `<scene>_<spp>spp_randImg.exr` (PT) and `..._corrImg.exr`
//! (CRN), each with four sub-buffer files `..._randImg0.exr` … `..._randImg3.exr`.
//! Reading it lets data rendered elsewhere be reconstructed and compared with cvtrace.
use crate::exr_io::read_rgb;
use crate::{Image, Stream, StreamError, StreamMeta, StreamSet};
use std::path::{Path, PathBuf};

/// Number of sub-buffers per stream in IDUW's layout.
pub const SUB_BUFFERS: usize = 4;

/// The files of one IDUW input: `dir/<scene>_<spp>spp_{randImg,corrImg}{,0..3}.exr`.
pub fn iduw_paths(dir: &Path, scene: &str, spp: u32) -> [(PathBuf, Vec<PathBuf>); 2] {
    ["randImg", "corrImg"].map(|kind| {
        let stem = format!("{scene}_{spp}spp_{kind}");
        let main = dir.join(format!("{stem}.exr"));
        let subs = (0..SUB_BUFFERS).map(|i| dir.join(format!("{stem}{i}.exr"))).collect();
        (main, subs)
    })
}

/// Given the path of any `..._randImg.exr` or `..._corrImg.exr` file, finds scene, spp and directory.
pub fn parse_iduw_name(path: &Path) -> Option<(PathBuf, String, u32)> {
    let name = path.file_name()?.to_str()?;
    let stem = name.strip_suffix(".exr")?;
    let stem = stem.strip_suffix("_randImg").or_else(|| stem.strip_suffix("_corrImg"))?;
    let (scene, spp) = stem.rsplit_once('_')?;
    let spp: u32 = spp.strip_suffix("spp")?.parse().ok()?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    Some((dir, scene.to_string(), spp))
}

/// Reads an IDUW input set into a [`StreamSet`] with 4 batches per stream and no features.
/// The stream means are taken from the main files; sub-buffers must have the same size.
pub fn read_iduw(dir: &Path, scene: &str, spp: u32) -> Result<StreamSet, StreamError> {
    let [(pt_main, pt_subs), (crn_main, crn_subs)] = iduw_paths(dir, scene, spp);
    let read_stream = |main: &PathBuf, subs: &Vec<PathBuf>| -> Result<Stream, StreamError> {
        let mean = read_rgb(main)?;
        let mut batches: Vec<Image> = Vec::with_capacity(SUB_BUFFERS);
        for p in subs {
            let im = read_rgb(p)?;
            if !im.same_size(&mean) {
                return Err(StreamError::SizeMismatch {
                    a: main.display().to_string(),
                    aw: mean.width,
                    ah: mean.height,
                    b: p.display().to_string(),
                    bw: im.width,
                    bh: im.height,
                });
            }
            batches.push(im);
        }
        Ok(Stream { mean, batches })
    };
    let pt = read_stream(&pt_main, &pt_subs)?;
    let crn = read_stream(&crn_main, &crn_subs)?;
    if !pt.mean.same_size(&crn.mean) {
        return Err(StreamError::SizeMismatch {
            a: pt_main.display().to_string(),
            aw: pt.mean.width,
            ah: pt.mean.height,
            b: crn_main.display().to_string(),
            bw: crn.mean.width,
            bh: crn.mean.height,
        });
    }
    let set = StreamSet {
        width: pt.mean.width,
        height: pt.mean.height,
        pt,
        crn,
        features: None,
        meta: StreamMeta { spp, scene: scene.to_string(), max_depth: -1, ..Default::default() },
    };
    set.validate(&pt_main)?;
    Ok(set)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exr_io::write_rgb;

    #[test]
    fn parses_names() {
        let (d, s, n) = parse_iduw_name(Path::new("/data/kitchen_64spp_corrImg.exr")).unwrap();
        assert_eq!((d, s.as_str(), n), (PathBuf::from("/data"), "kitchen", 64));
        assert!(parse_iduw_name(Path::new("kitchen_corrImg.exr")).is_none());
    }

    #[test]
    fn reads_a_written_layout_and_reports_missing_files() {
        let dir = tempfile::tempdir().unwrap();
        for (main, subs) in iduw_paths(dir.path(), "toy", 16) {
            // Sub-buffer i holds x + i (i = 1..4); the main image is their mean, x + 2.5.
            for (i, p) in std::iter::once(&main).chain(subs.iter()).enumerate() {
                let v = if i == 0 { 2.5 } else { i as f32 };
                write_rgb(p, &Image::from_fn(4, 2, |x, _| [x as f32 + v, 0.0, 1.0]), &[], false).unwrap();
            }
        }
        let set = read_iduw(dir.path(), "toy", 16).unwrap();
        assert_eq!(set.batch_count(), 4);
        assert_eq!(set.crn.batches[2].get(1, 0)[0], 4.0);
        // A main image that is not the mean of its sub-buffers is refused.
        let main = dir.path().join("toy_16spp_randImg.exr");
        write_rgb(&main, &Image::from_fn(4, 2, |x, _| [x as f32, 0.0, 1.0]), &[], true).unwrap();
        let e = read_iduw(dir.path(), "toy", 16).unwrap_err().to_string();
        assert!(e.contains("toy_16spp_randImg.exr") && e.contains("mean of its batches"), "{e}");
        std::fs::remove_file(dir.path().join("toy_16spp_corrImg3.exr")).unwrap();
        let e = read_iduw(dir.path(), "toy", 16).unwrap_err().to_string();
        assert!(e.contains("toy_16spp_corrImg3.exr"), "{e}");
    }
}
