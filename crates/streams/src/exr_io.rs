//! Flat f32 multi-channel OpenEXR read/write: the one place that talks to the `exr` crate.
use crate::atomic::write_atomically;
use crate::StreamError;
use exr::prelude::{read, AnyChannel, AnyChannels, AttributeValue, Blocks, Compression, Encoding, FlatSamples, Layer, LayerAttributes, LineOrder, ReadChannels, ReadLayers, SmallVec, Text, WritableImage};
use std::collections::BTreeMap;
use std::path::Path;

/// A header attribute value. Integers that fit are stored as EXR `int`, the rest as `string`.
#[derive(Clone, Debug, PartialEq)]
pub enum AttrValue {
    Int(i32),
    Float(f32),
    Text(String),
}

impl AttrValue {
    pub fn as_text(&self) -> String {
        match self {
            AttrValue::Int(v) => v.to_string(),
            AttrValue::Float(v) => v.to_string(),
            AttrValue::Text(s) => s.clone(),
        }
    }
}

/// All channels of a single-part scanline EXR as f32 planes, plus its custom attributes.
#[derive(Clone, Debug, Default)]
pub struct ExrChannels {
    pub width: usize,
    pub height: usize,
    pub channels: BTreeMap<String, Vec<f32>>,
    pub attributes: BTreeMap<String, AttrValue>,
}

impl ExrChannels {
    pub fn new(width: usize, height: usize) -> Self {
        ExrChannels { width, height, ..Default::default() }
    }

    pub fn insert(&mut self, name: impl Into<String>, plane: Vec<f32>) {
        assert_eq!(plane.len(), self.width * self.height, "channel plane has the wrong length");
        self.channels.insert(name.into(), plane);
    }

    /// The plane of `name`, or an error naming the file and the channel.
    pub fn take(&mut self, path: &Path, name: &str) -> Result<Vec<f32>, StreamError> {
        self.channels
            .remove(name)
            .ok_or_else(|| StreamError::MissingChannel { path: path.to_path_buf(), channel: name.to_string() })
    }

    pub fn attr(&self, name: &str) -> Option<&AttrValue> {
        self.attributes.get(name)
    }

    /// Reads every channel of `path` (f16 and u32 samples are converted to f32).
    pub fn read(path: &Path) -> Result<Self, StreamError> {
        if !path.exists() {
            return Err(StreamError::Io {
                path: path.to_path_buf(),
                error: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
            });
        }
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(path)
            .map_err(|e| StreamError::Exr { path: path.to_path_buf(), message: e.to_string() })?;
        if image.layer_data.len() != 1 {
            return Err(StreamError::invalid(
                path,
                format!("expected a single-part EXR, found {} parts", image.layer_data.len()),
            ));
        }
        let layer = &image.layer_data[0];
        let (width, height) = (layer.size.width(), layer.size.height());
        let mut out = ExrChannels::new(width, height);
        let prefix = layer.attributes.layer_name.as_ref().map(|n| format!("{n}."));
        for ch in &layer.channel_data.list {
            let mut name = ch.name.to_string();
            if let Some(p) = &prefix {
                // A named single layer whose channels are bare (`R` in layer `pt`): give them
                // their full dotted names. Channels already dotted (`pt.R`, as cvtrace and most
                // tools write them, whatever the part's name) are kept as they are.
                if !name.contains('.') {
                    name = format!("{p}{name}");
                }
            }
            let plane: Vec<f32> = ch.sample_data.values_as_f32().collect();
            out.channels.insert(name, plane);
        }
        out.attributes = custom_attributes(image.attributes.other.iter().chain(layer.attributes.other.iter()));
        Ok(out)
    }

    /// Size and custom attributes of `path` from its header alone, without reading pixels
    /// (to check what a finished file was rendered with before reusing it).
    pub fn read_header(path: &Path) -> Result<(usize, usize, BTreeMap<String, AttrValue>), StreamError> {
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .map_err(|e| StreamError::Exr { path: path.to_path_buf(), message: e.to_string() })?;
        let [header] = meta.headers.as_slice() else {
            return Err(StreamError::invalid(path, format!("expected a single-part EXR, found {} parts", meta.headers.len())));
        };
        let attributes = custom_attributes(header.shared_attributes.other.iter().chain(header.own_attributes.other.iter()));
        Ok((header.layer_size.width(), header.layer_size.height(), attributes))
    }
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

    /// Writes a single-part, ZIP-compressed, f32 scanline EXR atomically.
    pub fn write(&self, path: &Path, overwrite: bool) -> Result<(), StreamError> {
        crate::atomic::check_extension(path, "exr")?;
        let size = (self.width, self.height);
        let list: SmallVec<[AnyChannel<FlatSamples>; 4]> = self
            .channels
            .iter()
            .map(|(name, plane)| AnyChannel::new(name.as_str(), FlatSamples::F32(plane.clone())))
            .collect();
        let channels = AnyChannels::sort(list);
        let mut attributes = LayerAttributes::default();
        for (k, v) in &self.attributes {
            let value = match v {
                AttrValue::Int(i) => AttributeValue::I32(*i),
                AttrValue::Float(f) => AttributeValue::F32(*f),
                // UTF-8 bytes: the exr crate only builds Latin-1 text (it panics on anything
                // else, such as a scene path in Chinese), while OpenEXR strings are plain bytes
                // that OpenImageIO reads as UTF-8.
                AttrValue::Text(s) => AttributeValue::Text(Text::from_slice_unchecked(s.as_bytes())),
            };
            attributes.other.insert(Text::new_or_panic(k.as_str()), value);
        }
        let encoding = Encoding { compression: Compression::ZIP16, blocks: Blocks::ScanLines, line_order: LineOrder::Increasing };
        let layer = Layer::new(size, attributes, encoding, channels);
        let image = exr::image::Image::from_layer(layer);
        write_atomically(path, overwrite, |tmp| -> Result<(), String> {
            image.write().to_file(tmp).map_err(|e| e.to_string())?;
            sort_header_attributes(tmp).map_err(|e| e.to_string())
        })
    }
}

/// Rewrites the header of a single-part EXR with its attributes sorted by name.
///
/// The `exr` crate keeps custom attributes in a `HashMap`, so their order in the file (not
/// their values) changes from run to run. OpenEXR readers look attributes up by name, so the
/// order is free; sorting it makes equal images give byte-identical files. The header keeps
/// its length, so the chunk offsets after it stay valid.
fn sort_header_attributes(path: &Path) -> std::io::Result<()> {
    use std::io::{Read, Seek, SeekFrom, Write};
    let bad = |m: &str| std::io::Error::new(std::io::ErrorKind::InvalidData, m.to_string());
    let mut file = std::fs::OpenOptions::new().read(true).write(true).open(path)?;
    let mut head = Vec::new();
    Read::by_ref(&mut file).take(1 << 20).read_to_end(&mut head)?;
    if head.len() < 8 || head[..4] != [0x76, 0x2f, 0x31, 0x01] {
        return Err(bad("not an OpenEXR file"));
    }
    if head[5] & 0x10 != 0 {
        return Err(bad("multi-part files are not sorted"));
    }
    let cstr_end = |from: usize| head[from..].iter().position(|&b| b == 0).map(|i| from + i);
    let mut attributes: Vec<&[u8]> = Vec::new();
    let mut at = 8;
    loop {
        let name_end = cstr_end(at).ok_or_else(|| bad("header runs past 1 MiB"))?;
        if name_end == at {
            break; // the empty name that ends the header
        }
        let type_end = cstr_end(name_end + 1).ok_or_else(|| bad("truncated attribute type"))?;
        let size_at = type_end + 1;
        let size_bytes: [u8; 4] = head.get(size_at..size_at + 4).ok_or_else(|| bad("truncated attribute size"))?.try_into().unwrap();
        let end = size_at + 4 + i32::from_le_bytes(size_bytes).max(0) as usize;
        if end > head.len() {
            return Err(bad("truncated attribute value"));
        }
        attributes.push(&head[at..end]);
        at = end;
    }
    // Sort by name (the bytes up to the first NUL).
    attributes.sort_by(|a, b| a.split(|&c| c == 0).next().cmp(&b.split(|&c| c == 0).next()));
    let sorted: Vec<u8> = attributes.concat();
    debug_assert_eq!(sorted.len(), at - 8);
    file.seek(SeekFrom::Start(8))?;
    file.write_all(&sorted)
}

/// Reads an RGB image from channels `{prefix}R/G/B` (prefix "" for a plain beauty image).
pub fn read_rgb(path: &Path) -> Result<crate::Image, StreamError> {
    let mut ch = ExrChannels::read(path)?;
    take_rgb(&mut ch, path, "")
}

/// Removes `{prefix}R/G/B` from `ch` and returns them as an image, rejecting non-finite values.
pub fn take_rgb(ch: &mut ExrChannels, path: &Path, prefix: &str) -> Result<crate::Image, StreamError> {
    if prefix.is_empty() && !ch.channels.contains_key("R") && ch.channels.contains_key("pt.R") {
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
pub fn write_rgb(
    path: &Path,
    img: &crate::Image,
    attributes: &[(&str, AttrValue)],
    overwrite: bool,
) -> Result<(), StreamError> {
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
        write_rgb(&p, &img, &[("cvtrace.spp", AttrValue::Int(7)), ("cvtrace.note", AttrValue::Text("hi".into()))], false)
            .unwrap();
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
        write_rgb(&p, &img, &[("cvtrace.spp", AttrValue::Int(7)), ("cvtrace.traversal", AttrValue::Text("fast".into()))], false)
            .unwrap();
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
