//! Files whose header is wrong in a way the fuzzer of cvtrace's EXR inputs found: each one is an
//! error naming the file, not an abort, a multi-GiB allocation or a silently misread image.
use cvtrace_streams::exr_io::{read_rgb, write_rgb, ExrChannels};
use cvtrace_streams::{Image, Stream, StreamMeta, StreamSet};
use exr::image::{AnyImage, Levels};
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, IntegerBounds, Text};
use exr::prelude::{FlatSamples, WritableImage};
use std::path::{Path, PathBuf};

fn streams(w: usize, h: usize) -> StreamSet {
    let batch = |s: f32, b: usize| Image::from_fn(w, h, |x, y| [s + x as f32, y as f32 + 0.5, b as f32]);
    StreamSet {
        width: w,
        height: h,
        pt: Stream::from_batches((0..4).map(|b| batch(1.0, b)).collect()),
        crn: Stream::from_batches((0..4).map(|b| batch(2.0, b)).collect()),
        features: None,
        meta: StreamMeta { spp: 8, max_depth: -1, ..Default::default() },
    }
}

/// Writes a small stream file, lets `edit` change it through the `exr` crate, and returns the
/// path of the edited file.
fn edited(dir: &Path, name: &str, edit: impl FnOnce(&mut AnyImage)) -> PathBuf {
    let p = dir.join("valid.streams.exr");
    if !p.exists() {
        streams(6, 4).write(&p, false).unwrap();
    }
    let mut image = exr::prelude::read_all_data_from_file(&p).unwrap();
    edit(&mut image);
    let q = dir.join(name);
    image.write().to_file(&q).unwrap();
    q
}

/// Overwrites the value of header attribute `name` (of `size` bytes) in the file's bytes.
fn patch_attribute(bytes: &mut [u8], name: &str, value: &[u8]) {
    let key = [name.as_bytes(), b"\0"].concat();
    let at = bytes.windows(key.len()).position(|w| w == key.as_slice()).unwrap_or_else(|| panic!("no attribute {name}"));
    let type_end = at + key.len() + bytes[at + key.len()..].iter().position(|&b| b == 0).unwrap() + 1;
    let size = i32::from_le_bytes(bytes[type_end..type_end + 4].try_into().unwrap()) as usize;
    assert_eq!(size, value.len(), "{name}");
    bytes[type_end + 4..type_end + 4 + size].copy_from_slice(value);
}

fn window(x1: i32, y1: i32) -> Vec<u8> {
    [0i32, 0, x1, y1].iter().flat_map(|v| v.to_le_bytes()).collect()
}

#[test]
fn a_header_claiming_more_pixels_than_the_file_holds_is_refused_before_allocating_them() {
    // Found by fuzzing: a 67 kB stream whose data window (and chunk count) claimed 65536×65536
    // pixels made the `exr` crate allocate 16 GiB per channel, and the process aborted
    // ("memory allocation of 17179869184 bytes failed"); a flipped byte in the data window
    // did the same.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.streams.exr");
    streams(6, 4).write(&p, false).unwrap();
    let mut bytes = std::fs::read(&p).unwrap();
    patch_attribute(&mut bytes, "dataWindow", &window(65535, 65535));
    patch_attribute(&mut bytes, "displayWindow", &window(65535, 65535));
    patch_attribute(&mut bytes, "chunkCount", &(65536i32 / 16).to_le_bytes());
    let q = dir.path().join("claims-65536.streams.exr");
    std::fs::write(&q, &bytes).unwrap();
    for e in [StreamSet::read(&q).unwrap_err().to_string(), read_rgb(&q).unwrap_err().to_string()] {
        assert!(e.contains("claims-65536.streams.exr") && e.contains("claims 65536x65536 pixels") && e.contains("corrupt"), "{e}");
    }
    // The same file with its true size reads.
    assert_eq!(StreamSet::read(&p).unwrap().width, 6);
}

#[test]
fn a_known_attribute_of_another_exr_type_is_not_read_as_missing() {
    // Found by fuzzing: `cvtrace.spp` stored as a v2f read as absent (spp unknown), and
    // `cvtrace.batches` as a box2i was ignored and the batches counted from the channels.
    let dir = tempfile::tempdir().unwrap();
    for (name, value) in [
        ("cvtrace.spp", AttributeValue::FloatVec2(Vec2(8.0, 8.0))),
        ("cvtrace.batches", AttributeValue::IntegerBounds(IntegerBounds::from_dimensions((4, 4)))),
        ("cvtrace.seed", AttributeValue::F64(3.0)),
    ] {
        let q = edited(dir.path(), "typed.streams.exr", |image| {
            image.layer_data[0].attributes.other.insert(Text::from(name), value.clone());
        });
        let e = StreamSet::read(&q).unwrap_err().to_string();
        assert!(e.contains("typed.streams.exr") && e.contains(&format!("attribute {name} has EXR type")), "{e}");
    }
}

#[test]
fn integer_channels_are_not_taken_for_radiance_or_features() {
    // Found by fuzzing: features (and references) stored as u32 were converted to whole
    // numbers and used without a word.
    let dir = tempfile::tempdir().unwrap();
    let q = edited(dir.path(), "uint.streams.exr", |image| {
        for ch in image.layer_data[0].channel_data.list.iter_mut() {
            if ch.name.to_string() == "crn.b02.G" {
                let Levels::Singular(samples) = &ch.sample_data else { unreachable!() };
                let ints: Vec<u32> = samples.values_as_f32().map(|v| v as u32).collect();
                ch.sample_data = Levels::Singular(FlatSamples::U32(ints));
            }
        }
    });
    let e = StreamSet::read(&q).unwrap_err().to_string();
    assert!(e.contains("uint.streams.exr") && e.contains("`crn.b02.G` holds 32-bit unsigned integers"), "{e}");
    // An unused integer channel (an object id next to the beauty) is fine.
    let r = dir.path().join("id.exr");
    write_rgb(&r, &Image::from_fn(3, 2, |x, _| [x as f32; 3]), &[], false).unwrap();
    let mut image = exr::prelude::read_all_data_from_file(&r).unwrap();
    let id = exr::prelude::AnyChannel::new("id", Levels::Singular(FlatSamples::U32(vec![7; 6])));
    image.layer_data[0].channel_data.list.push(id);
    image.layer_data[0].channel_data.list.sort_by(|a, b| a.name.cmp(&b.name));
    image.write().to_file(&r).unwrap();
    assert_eq!(read_rgb(&r).unwrap().get(2, 1), [2.0; 3]);
    assert!(ExrChannels::read(&r).unwrap().integer_channels.contains("id"));
}

#[test]
fn images_that_are_not_whole_frames_at_the_origin_are_refused() {
    // Found by fuzzing: a reference whose data window started at (5, 3) was compared pixel by
    // pixel with streams starting at (0, 0), and a crop (data window inside a larger display
    // window) read as if it were the whole image.
    let dir = tempfile::tempdir().unwrap();
    let q = edited(dir.path(), "offset.streams.exr", |image| {
        image.layer_data[0].attributes.layer_position = Vec2(5, 3);
        image.attributes.display_window = IntegerBounds::new((5, 3), (6, 4));
    });
    let e = StreamSet::read(&q).unwrap_err().to_string();
    assert!(e.contains("offset.streams.exr") && e.contains("(5, 3)–(10, 6) does not start at (0, 0)"), "{e}");
    let q = edited(dir.path(), "crop.streams.exr", |image| {
        image.attributes.display_window = IntegerBounds::new((0, 0), (64, 48));
    });
    let e = read_rgb(&q).unwrap_err().to_string();
    assert!(e.contains("crop.streams.exr") && e.contains("data window (0, 0)–(5, 3) is not its display window (0, 0)–(63, 47)"), "{e}");
}

#[test]
fn fifos_devices_and_folders_are_refused_not_read() {
    // A FIFO would block the reader forever, /dev/zero never end; any caller of the library
    // gets an error naming the path at once.
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.exr");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    for p in [fifo.as_path(), Path::new("/dev/zero"), dir.path()] {
        for e in [
            ExrChannels::read(p).map(|_| ()).unwrap_err(),
            ExrChannels::read_header(p).map(|_| ()).unwrap_err(),
            read_rgb(p).map(|_| ()).unwrap_err(),
        ] {
            let e = e.to_string();
            assert!(e.contains(&p.display().to_string()) && (e.contains("not a regular file") || e.contains("is a directory")), "{e}");
        }
    }
}
