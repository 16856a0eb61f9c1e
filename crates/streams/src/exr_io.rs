//! Flat f32 multi-channel OpenEXR read/write: the one place that talks to the `exr` crate.
use crate::block_writer::{write_by_blocks, ExrLayout, Late, ROWS_PER_BLOCK};
use crate::input_file::NotAFile;
use crate::StreamError;
use exr::prelude::{read, AttributeValue, FlatSamples, ReadChannels, ReadLayers, Text};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

pub use crate::attr::AttrValue;

/// All channels of a single-part scanline EXR as f32 planes, plus its custom attributes.
#[derive(Clone, Debug, Default)]
pub struct ExrChannels {
    pub width: usize,
    pub height: usize,
    pub channels: BTreeMap<String, Vec<f32>>,
    pub attributes: BTreeMap<String, AttrValue>,
    /// Custom attributes of other EXR types than `int`, `float` and `string`, as name → type
    /// name (`v2f`, `box2i`, …): not read, but a reader can tell a mistyped attribute from a
    /// missing one.
    pub other_attributes: BTreeMap<String, String>,
    /// Channels stored as 32-bit unsigned integers (converted to f32 in `channels`): ids or
    /// masks, never radiance; [`ExrChannels::take`] refuses them.
    pub integer_channels: BTreeSet<String>,
}

impl ExrChannels {
    pub fn new(width: usize, height: usize) -> Self {
        ExrChannels { width, height, ..Default::default() }
    }

    pub fn insert(&mut self, name: impl Into<String>, plane: Vec<f32>) {
        assert_eq!(plane.len(), self.width * self.height, "channel plane has the wrong length");
        let name = name.into();
        self.integer_channels.remove(&name);
        self.channels.insert(name, plane);
    }

    /// The plane of `name`, or an error naming the file and the channel (also when the file
    /// stores it as integers: converted, they would pass for radiance or features).
    pub fn take(&mut self, path: &Path, name: &str) -> Result<Vec<f32>, StreamError> {
        if self.integer_channels.contains(name) {
            return Err(StreamError::invalid(
                path,
                format!("channel `{name}` holds 32-bit unsigned integers, not floating-point values; write it as float (or half)"),
            ));
        }
        self.channels.remove(name).ok_or_else(|| StreamError::MissingChannel { path: path.to_path_buf(), channel: name.to_string() })
    }

    pub fn attr(&self, name: &str) -> Option<&AttrValue> {
        self.attributes.get(name)
    }

    /// Reads every channel of `path` (f16 and u32 samples are converted to f32; u32 channels
    /// are listed in `integer_channels`). The header is checked first ([`check_header`]), so
    /// that a corrupt or absurd one is an error before any pixel memory is allocated.
    pub fn read(path: &Path) -> Result<Self, StreamError> {
        if !path.exists() {
            return Err(StreamError::Io {
                path: path.to_path_buf(),
                error: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
            });
        }
        check_header(path)?;
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(path)
            .map_err(|e| StreamError::Exr { path: path.to_path_buf(), message: e.to_string() })?;
        if image.layer_data.len() != 1 {
            return Err(StreamError::invalid(path, format!("expected a single-part EXR, found {} parts", image.layer_data.len())));
        }
        let layer = image.layer_data.into_iter().next().expect("one layer");
        let (width, height) = (layer.size.width(), layer.size.height());
        let mut out = ExrChannels::new(width, height);
        let attrs = || image.attributes.other.iter().chain(layer.attributes.other.iter());
        out.attributes = custom_attributes(attrs());
        out.other_attributes = attrs()
            .filter(|(k, _)| !out.attributes.contains_key(&k.to_string()))
            .map(|(k, v)| (k.to_string(), String::from_utf8_lossy(v.kind_name()).into_owned()))
            .collect();
        let prefix = layer.attributes.layer_name.as_ref().map(|n| format!("{n}."));
        for ch in layer.channel_data.list {
            let mut name = ch.name.to_string();
            if let Some(p) = &prefix {
                // A named single layer whose channels are bare (`R` in layer `pt`): give them
                // their full dotted names. Channels already dotted (`pt.R`, as cvtrace and most
                // tools write them, whatever the part's name) are kept as they are.
                if !name.contains('.') {
                    name = format!("{p}{name}");
                }
            }
            // f32 planes (what cvtrace writes) are moved, not copied.
            let plane: Vec<f32> = match ch.sample_data {
                FlatSamples::F32(v) => v,
                FlatSamples::U32(v) => {
                    out.integer_channels.insert(name.clone());
                    v.into_iter().map(|x| x as f32).collect()
                }
                other => other.values_as_f32().collect(),
            };
            out.channels.insert(name, plane);
        }
        Ok(out)
    }

    /// Size and custom attributes of `path` from its header alone, without reading pixels
    /// (to check what a finished file was rendered with before reusing it).
    pub fn read_header(path: &Path) -> Result<(usize, usize, BTreeMap<String, AttrValue>), StreamError> {
        require_regular_file(path)?;
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .map_err(|e| StreamError::Exr { path: path.to_path_buf(), message: e.to_string() })?;
        let [header] = meta.headers.as_slice() else {
            return Err(StreamError::invalid(path, format!("expected a single-part EXR, found {} parts", meta.headers.len())));
        };
        let attributes = custom_attributes(header.shared_attributes.other.iter().chain(header.own_attributes.other.iter()));
        Ok((header.layer_size.width(), header.layer_size.height(), attributes))
    }
}

/// `path` must be a regular file (a FIFO would block the read forever, a device never end
/// it); returns its length.
fn require_regular_file(path: &Path) -> Result<u64, StreamError> {
    crate::input_file::regular_file(path).map_err(|e| match e {
        NotAFile::Io(error) => StreamError::Io { path: path.to_path_buf(), error },
        other => StreamError::invalid(path, other.to_string()),
    })
}

/// Largest ratio of decoded pixel bytes to file bytes that `compression` can reach: deflate
/// (ZIP, and the other codecs that end in it) cannot expand more than 1032:1, PXR24 stores 3
/// of an f32's 4 bytes before deflating, RLE turns 2 bytes into at most 128, and DWA's DCT can
/// describe an 8×8 block by its deflated DC value alone.
fn max_expansion(compression: exr::compression::Compression) -> u128 {
    use exr::compression::Compression::*;
    match compression {
        Uncompressed => 1,
        RLE => 64,
        PXR24 => 1400,
        DWAA(_) | DWAB(_) | HTJ2K32 | HTJ2K256 => 1100 * 64,
        _ => 1100,
    }
}

/// Checks what the header of `path` promises before any pixel is read: one flat part, a pixel
/// count that the file's bytes can hold, a data window that is the display window at the
/// origin (cvtrace pairs pixels by index, so an offset or cropped image would be compared with
/// the wrong pixels of another file), and memory this process can allocate for the read. A
/// corrupt header claiming billions of pixels would otherwise have the `exr` crate allocate
/// them all, which aborts the process instead of failing.
pub fn check_header(path: &Path) -> Result<(), StreamError> {
    let exr_error = |e: exr::error::Error| StreamError::Exr { path: path.to_path_buf(), message: e.to_string() };
    let file_len = require_regular_file(path)?;
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(exr_error)?;
    if let Some(h) = meta.headers.iter().find(|h| h.deep) {
        let name = h.own_attributes.layer_name.as_ref().map(|n| format!(" (part `{n}`)")).unwrap_or_default();
        return Err(StreamError::invalid(
            path,
            format!("holds deep data{name}: cvtrace reads flat images with one value per pixel and channel"),
        ));
    }
    exr::meta::MetaData::validate(&meta.headers, false).map_err(exr_error)?;
    let [header] = meta.headers.as_slice() else {
        return Err(StreamError::invalid(path, format!("expected a single-part EXR, found {} parts", meta.headers.len())));
    };
    let (w, h) = (header.layer_size.width() as u128, header.layer_size.height() as u128);
    let channels = header.channels.list.len() as u128;
    let decoded: u128 = header.channels.list.iter().map(|c| w * h * c.sample_type.bytes_per_sample() as u128).sum();
    const GIB: f64 = (1u64 << 30) as f64;
    if decoded > file_len as u128 * max_expansion(header.compression) {
        return Err(StreamError::invalid(
            path,
            format!(
                "its header claims {w}x{h} pixels in {channels} channels ({:.2} GiB of samples), more than its {file_len} bytes can hold with {}: the file is truncated or its header is corrupt",
                decoded as f64 / GIB,
                header.compression
            ),
        ));
    }
    let data = header.data_window();
    let display = header.shared_attributes.display_window;
    let corners = |b: exr::meta::attribute::IntegerBounds| {
        let max = b.max();
        format!("({}, {})–({}, {})", b.position.x(), b.position.y(), max.x(), max.y())
    };
    if data != display {
        return Err(StreamError::invalid(
            path,
            format!(
                "its data window {} is not its display window {}: cvtrace reads whole images only (oiiotool {} --origin +0+0 --fullpixels -o whole.exr makes the data the whole image)",
                corners(data),
                corners(display),
                path.display()
            ),
        ));
    }
    if data.position.x() != 0 || data.position.y() != 0 {
        return Err(StreamError::invalid(
            path,
            format!(
                "its image window {} does not start at (0, 0): pixels are paired with other files by position (oiiotool {} --origin +0+0 --fullpixels -o moved.exr moves it)",
                corners(data),
                path.display()
            ),
        ));
    }
    // Reading holds the decoded samples and their f32 copies at once. Ask for that much first,
    // so that an image too large for this machine (or for `ulimit -v`) is an error, not an abort.
    let needed = decoded + w * h * channels * 4;
    let fits = usize::try_from(needed).ok().is_some_and(|n| Vec::<u8>::new().try_reserve_exact(n).is_ok());
    if !fits {
        return Err(StreamError::invalid(
            path,
            format!(
                "reading its {w}x{h} pixels in {channels} channels needs {:.2} GiB of memory, which cannot be allocated here",
                needed as f64 / GIB
            ),
        ));
    }
    Ok(())
}

/// The integer, float and text attributes among `attrs` (other kinds are not used by cvtrace).
/// An attribute's text: UTF-8 (as cvtrace writes it), or Latin-1 for bytes that are not UTF-8.
fn text_of(t: &Text) -> String {
    String::from_utf8(t.bytes().to_vec()).unwrap_or_else(|_| t.to_string())
}

fn custom_attributes<'a>(attrs: impl Iterator<Item = (&'a Text, &'a AttributeValue)>) -> BTreeMap<String, AttrValue> {
    attrs
        .filter_map(|(k, v)| {
            let value = match v {
                AttributeValue::I32(i) => AttrValue::Int(*i),
                AttributeValue::F32(f) => AttrValue::Float(*f),
                AttributeValue::Text(t) => AttrValue::Text(text_of(t)),
                _ => return None,
            };
            Some((k.to_string(), value))
        })
        .collect()
}

impl ExrChannels {
    /// Writes a single-part, ZIP-compressed, f32 scanline EXR atomically, block by block from
    /// the planes (no copy of them is made).
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<(), StreamError> {
        let layout = ExrLayout::new(self.width, self.height, self.channels.keys().cloned(), self.attributes.clone());
        // `layout.channels` is sorted as the map's keys are.
        let planes: Vec<&[f32]> = self.channels.values().map(Vec::as_slice).collect();
        let w = self.width;
        let fill = |c: usize, y: usize, out: &mut [f32]| out.copy_from_slice(&planes[c][y * w..(y + 1) * w]);
        write_by_blocks(path, overwrite, &layout, |sink| -> Result<Late, StreamError> {
            // A few blocks per thread at a time: parallel, and never more than those compressed.
            let step = ROWS_PER_BLOCK * (4 * rayon::current_num_threads()).max(8);
            for y0 in (0..self.height).step_by(step) {
                sink.put(y0..(y0 + step).min(self.height), &fill)?;
            }
            Ok(Late::new())
        })
    }
}

/// Reads an RGB image (a reference, a reconstruction) from its channels `R/G/B`. A stream
/// file is refused: its top-level layer is only a picture of it, not an image to score.
pub fn read_rgb(path: &Path) -> Result<crate::Image, StreamError> {
    let mut ch = ExrChannels::read(path)?;
    take_rgb(&mut ch, path, "")
}

/// The top-level `R/G/B` of any cvtrace file: an image, or a stream file's picture (the mean
/// of both streams), for previews.
pub fn read_picture(path: &Path) -> Result<crate::Image, StreamError> {
    let mut ch = ExrChannels::read(path)?;
    ch.channels.remove("pt.R");
    take_rgb(&mut ch, path, "")
}

/// Removes `{prefix}R/G/B` from `ch` and returns them as an image, rejecting non-finite values.
pub fn take_rgb(ch: &mut ExrChannels, path: &Path, prefix: &str) -> Result<crate::Image, StreamError> {
    if prefix.is_empty() && ch.channels.contains_key("pt.R") {
        return Err(StreamError::invalid(
            path,
            "is a PT/CRN stream file, not an RGB image: reconstruct it first, or use a reference rendered with --reference",
        ));
    }
    let names = ["R", "G", "B"].map(|c| format!("{prefix}{c}"));
    let planes = [ch.take(path, &names[0])?, ch.take(path, &names[1])?, ch.take(path, &names[2])?];
    let img = crate::Image::from_channels(ch.width, ch.height, [&planes[0], &planes[1], &planes[2]]);
    if let Some((x, y, c)) = img.find_non_finite() {
        return Err(StreamError::NonFinite { path: path.to_path_buf(), channel: names[c].clone(), x, y });
    }
    Ok(img)
}

/// Adds an RGB image as channels `{prefix}R/G/B`.
pub fn put_rgb(ch: &mut ExrChannels, prefix: &str, img: &crate::Image) {
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        ch.insert(format!("{prefix}{name}"), img.channel(c));
    }
}

/// Writes a plain RGB EXR (channels R, G, B) with the given attributes.
pub fn write_rgb(path: &Path, img: &crate::Image, attributes: &[(&str, AttrValue)], overwrite: bool) -> Result<(), StreamError> {
    let mut ch = ExrChannels::new(img.width, img.height);
    put_rgb(&mut ch, "", img);
    for (k, v) in attributes {
        ch.attributes.insert(k.to_string(), v.clone());
    }
    ch.write(path, overwrite)
}

#[cfg(test)]
mod tests {
    use super::*;
    use exr::prelude::{AnyChannel, AnyChannels, Encoding, Layer, LayerAttributes, SmallVec, WritableImage};

    #[test]
    fn a_named_part_keeps_dotted_channel_names_and_completes_bare_ones() {
        // Other tools name the single part (`name` attribute); cvtrace's own files do not.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("named.exr");
        let plane = |v: f32| FlatSamples::F32(vec![v; 6]);
        let channels = AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new("pt.R", plane(1.0)), AnyChannel::new("G", plane(2.0))]));
        let layer = Layer::new((3, 2), LayerAttributes::named("a"), Encoding::SMALL_LOSSLESS, channels);
        exr::image::Image::from_layer(layer).write().to_file(&p).unwrap();
        let ch = ExrChannels::read(&p).unwrap();
        assert_eq!(ch.channels.keys().collect::<Vec<_>>(), ["a.G", "pt.R"]);
        assert_eq!(ch.channels["pt.R"], vec![1.0; 6]);
    }

    #[test]
    fn round_trip_keeps_channels_and_attributes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let img = crate::Image::from_fn(5, 3, |x, y| [x as f32, y as f32, 0.5]);
        write_rgb(&p, &img, &[("cvtrace.spp", AttrValue::Int(7)), ("cvtrace.note", AttrValue::Text("hi".into()))], false).unwrap();
        let back = read_rgb(&p).unwrap();
        assert_eq!(back, img);
        let ch = ExrChannels::read(&p).unwrap();
        assert_eq!(ch.attr("cvtrace.spp"), Some(&AttrValue::Int(7)));
        assert_eq!(ch.attr("cvtrace.note"), Some(&AttrValue::Text("hi".into())));
        // Text beyond Latin-1 (a scene path in Chinese) round-trips as UTF-8.
        let q = dir.path().join("utf8.exr");
        write_rgb(&q, &img, &[("cvtrace.scene", AttrValue::Text("场景/ü.gltf".into()))], false).unwrap();
        assert_eq!(ExrChannels::read(&q).unwrap().attr("cvtrace.scene"), Some(&AttrValue::Text("场景/ü.gltf".into())));
    }

    #[test]
    fn header_alone_gives_size_and_the_same_attributes() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let img = crate::Image::from_fn(5, 3, |x, _| [x as f32, 0.0, 1.0]);
        write_rgb(&p, &img, &[("cvtrace.spp", AttrValue::Int(7)), ("cvtrace.traversal", AttrValue::Text("fast".into()))], false).unwrap();
        let (w, h, attrs) = ExrChannels::read_header(&p).unwrap();
        assert_eq!((w, h), (5, 3));
        assert_eq!(attrs, ExrChannels::read(&p).unwrap().attributes);
        assert_eq!(attrs.get("cvtrace.traversal"), Some(&AttrValue::Text("fast".into())));
        let e = ExrChannels::read_header(&dir.path().join("missing.exr")).unwrap_err().to_string();
        assert!(e.contains("missing.exr"), "{e}");
    }

    #[test]
    fn equal_images_give_byte_identical_files() {
        let dir = tempfile::tempdir().unwrap();
        let img = crate::Image::from_fn(9, 4, |x, y| [x as f32, y as f32, 0.25]);
        let attrs: Vec<(String, AttrValue)> = (0..12).map(|i| (format!("cvtrace.a{i}"), AttrValue::Int(i))).collect();
        let attrs: Vec<(&str, AttrValue)> = attrs.iter().map(|(k, v)| (k.as_str(), v.clone())).collect();
        let files: Vec<Vec<u8>> = (0..4)
            .map(|i| {
                let p = dir.path().join(format!("{i}.exr"));
                write_rgb(&p, &img, &attrs, false).unwrap();
                std::fs::read(&p).unwrap()
            })
            .collect();
        assert!(files.windows(2).all(|w| w[0] == w[1]), "attribute order changed between writes");
        let back = ExrChannels::read(&dir.path().join("0.exr")).unwrap();
        assert_eq!(back.attr("cvtrace.a7"), Some(&AttrValue::Int(7)));
    }

    #[test]
    fn garbage_file_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.exr");
        std::fs::write(&p, b"not an exr at all").unwrap();
        let e = read_rgb(&p).unwrap_err().to_string();
        assert!(e.contains("bad.exr") && e.contains("OpenEXR"), "{e}");
    }

    #[test]
    fn missing_channel_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("g.exr");
        let mut ch = ExrChannels::new(2, 2);
        ch.insert("R", vec![0.0; 4]);
        ch.insert("G", vec![0.0; 4]);
        ch.write(&p, false).unwrap();
        let e = read_rgb(&p).unwrap_err().to_string();
        assert!(e.contains("g.exr") && e.contains("`B`"), "{e}");
    }
}
