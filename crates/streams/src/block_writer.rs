//! Writing a single-part, ZIP-compressed f32 scanline EXR block by block.
//!
//! The file is written from rows supplied by the caller, one run of whole blocks (16
//! scanlines each) at a time, so no copy of the whole image is ever made: a renderer can hand
//! over each band of rows as soon as it is finished and drop it. Blocks are compressed in
//! parallel on the current rayon pool (the caller's `-t` threads) and written in increasing
//! order with the `exr` crate's own header and chunk writer.
//!
//! The blocks are OpenEXR's ZIP (the byte predictor, then zlib), compressed by the same deflate
//! as the `exr` crate's, but at level 1 instead of its fixed level 4: on stream files that is
//! about 3.3× faster for files about 3% larger, and compressing is the one part of a stream
//! render a PT render does not have (docs/performance.md). Every ZIP reader decodes either.
use crate::atomic::write_atomically;
use crate::attr::AttrValue;
use crate::StreamError;
use exr::block::chunk::{Chunk, CompressedBlock, CompressedScanLineBlock};
use exr::block::writer::{ChunkWriter, ChunksWriter};
use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Blocks, Compression, Encoding, FlatSamples, Layer, LayerAttributes, LineOrder, SmallVec, Text,
};
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::ops::Range;
use std::path::Path;

/// Scanlines per ZIP block: every block but the last holds this many rows.
pub const ROWS_PER_BLOCK: usize = 16;

/// The deflate level of the blocks (miniz_oxide's scale, 0–10).
const DEFLATE_LEVEL: u8 = 1;

/// One ZIP block from its little-endian bytes (rows in turn, each row's channels in turn):
/// OpenEXR's predictor (the even bytes, then the odd ones, as differences to the byte before
/// plus 128), then zlib. Where that is not smaller the block is stored raw, as OpenEXR does.
fn zip_block(raw: Vec<u8>) -> Vec<u8> {
    let half = raw.len().div_ceil(2);
    let mut predicted = vec![0u8; raw.len()];
    let (evens, odds) = predicted.split_at_mut(half);
    for (i, pair) in raw.chunks(2).enumerate() {
        evens[i] = pair[0];
        if let Some(&b) = pair.get(1) {
            odds[i] = b;
        }
    }
    let mut previous = predicted.first().copied().unwrap_or(0);
    for b in predicted.iter_mut().skip(1) {
        let current = *b;
        *b = current.wrapping_sub(previous).wrapping_add(128);
        previous = current;
    }
    let compressed = miniz_oxide::deflate::compress_to_vec_zlib(&predicted, DEFLATE_LEVEL);
    if compressed.len() < raw.len() {
        compressed
    } else {
        raw
    }
}

/// What the file holds: its size, its channels (all f32) and its custom attributes.
#[derive(Clone, Debug)]
pub struct ExrLayout {
    pub width: usize,
    pub height: usize,
    /// Channel names, sorted as the file stores them (byte order).
    pub channels: Vec<String>,
    pub attributes: BTreeMap<String, AttrValue>,
}

impl ExrLayout {
    pub fn new(width: usize, height: usize, channels: impl IntoIterator<Item = String>, attributes: BTreeMap<String, AttrValue>) -> Self {
        let mut channels: Vec<String> = channels.into_iter().collect();
        channels.sort();
        channels.dedup();
        ExrLayout { width, height, channels, attributes }
    }

    /// The index of `name` in [`ExrLayout::channels`].
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.binary_search_by(|c| c.as_str().cmp(name)).ok()
    }

    /// The header the `exr` crate's own writer makes for these channels and attributes: a
    /// layer of empty planes gives it, since only the channels' names and sample type count.
    fn headers(&self) -> exr::meta::Headers {
        let list: SmallVec<[AnyChannel<FlatSamples>; 4]> =
            self.channels.iter().map(|name| AnyChannel::new(name.as_str(), FlatSamples::F32(Vec::new()))).collect();
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
        let layer = Layer::new((self.width, self.height), attributes, encoding, AnyChannels::sort(list));
        let image = exr::image::Image::from_layer(layer);
        exr::prelude::WritableImage::write(&image).infer_meta_data()
    }
}

/// Fills row `y` of channel `c` (an index into [`ExrLayout::channels`]) into `out`.
pub type RowFill<'a> = dyn Fn(usize, usize, &mut [f32]) + Sync + 'a;

/// Compressed blocks, ready to be written in their place.
pub struct CompressedBlocks {
    first: usize,
    chunks: Vec<Chunk>,
}

/// Takes the file's blocks in order; see [`write_by_blocks`].
pub struct BlockSink<'a> {
    path: &'a Path,
    writer: &'a mut ChunkWriter<BufWriter<File>>,
    width: usize,
    height: usize,
    channels: usize,
    next_block: usize,
}

impl BlockSink<'_> {
    /// Compresses the blocks of rows `rows`, which must start at a block boundary and end at one
    /// or at the image's last row, in parallel on the current rayon pool. Only `&self`: it can
    /// run while the caller produces the next rows.
    pub fn compress(&self, rows: Range<usize>, fill: &RowFill<'_>) -> Result<CompressedBlocks, StreamError> {
        assert!(rows.start.is_multiple_of(ROWS_PER_BLOCK), "rows {rows:?} do not start a block");
        assert!(rows.end == self.height || rows.end.is_multiple_of(ROWS_PER_BLOCK), "rows {rows:?} do not end a block");
        let first = rows.start / ROWS_PER_BLOCK;
        let end = rows.end.div_ceil(ROWS_PER_BLOCK);
        let (width, channels) = (self.width, self.channels);
        let chunks = (first..end)
            .into_par_iter()
            .map(|block| {
                let y0 = block * ROWS_PER_BLOCK;
                let y1 = (y0 + ROWS_PER_BLOCK).min(self.height);
                // Rows one after another, and in each row every channel's samples in turn.
                let mut data = Vec::with_capacity((y1 - y0) * channels * width * 4);
                let mut line = vec![0f32; width];
                for y in y0..y1 {
                    for c in 0..channels {
                        fill(c, y, &mut line);
                        data.extend(line.iter().flat_map(|v| v.to_le_bytes()));
                    }
                }
                let y_coordinate = i32::try_from(y0).map_err(|_| self.error(format!("row {y0} is beyond OpenEXR's range")))?;
                let block = CompressedScanLineBlock { y_coordinate, compressed_pixels_le: zip_block(data) };
                Ok(Chunk { layer_index: 0, compressed_block: CompressedBlock::ScanLine(block) })
            })
            .collect::<Result<Vec<Chunk>, StreamError>>()?;
        Ok(CompressedBlocks { first, chunks })
    }

    /// Writes `blocks`, which must be the next ones of the file.
    pub fn write(&mut self, blocks: CompressedBlocks) -> Result<(), StreamError> {
        assert_eq!(blocks.first, self.next_block, "blocks written out of order");
        for chunk in blocks.chunks {
            self.writer
                .write_chunk(self.next_block, chunk)
                .map_err(|e| StreamError::invalid(self.path, format!("could not write a block: {e}")))?;
            self.next_block += 1;
        }
        Ok(())
    }

    fn error(&self, e: impl std::fmt::Display) -> StreamError {
        StreamError::invalid(self.path, format!("could not compress a block: {e}"))
    }

    /// [`BlockSink::compress`] then [`BlockSink::write`].
    pub fn put(&mut self, rows: Range<usize>, fill: &RowFill<'_>) -> Result<(), StreamError> {
        let blocks = self.compress(rows, fill)?;
        self.write(blocks)
    }
}

/// Text attributes known only once every row is written (a count of replaced samples): name
/// → value. Each must be in the layout already, with a placeholder value.
pub type Late = BTreeMap<String, String>;

/// Writes the EXR of `layout` atomically to `path`: `produce` hands every block to the sink,
/// in order ([`BlockSink::compress`], [`BlockSink::write`]), and returns the [`Late`]
/// attributes. An error of `produce` is returned as it is (and nothing is left at `path`).
pub fn write_by_blocks<E: From<StreamError>>(
    path: &Path,
    overwrite: bool,
    layout: &ExrLayout,
    produce: impl FnOnce(&mut BlockSink<'_>) -> Result<Late, E>,
) -> Result<(), E> {
    crate::atomic::check_extension(path, "exr")?;
    let headers = layout.headers();
    let chunk_count = headers[0].chunk_count;
    let mut failure: Option<E> = None;
    let mut late = Late::new();
    let written = write_atomically(path, overwrite, |tmp| -> Result<(), String> {
        let file = File::create(tmp).map_err(|e| e.to_string())?;
        let result = exr::block::write(BufWriter::new(file), headers, true, |_, writer| {
            let mut sink =
                BlockSink { path, writer, width: layout.width, height: layout.height, channels: layout.channels.len(), next_block: 0 };
            match produce(&mut sink) {
                Ok(l) => {
                    late = l;
                    Ok(())
                }
                Err(e) => {
                    failure = Some(e);
                    Err(exr::error::Error::Aborted)
                }
            }
        });
        result.map_err(|e| e.to_string())?;
        finish_header(tmp, chunk_count, &late).map_err(|e| e.to_string())
    });
    match (written, failure) {
        (_, Some(e)) => Err(e),
        (Err(e), None) => Err(e.into()),
        (Ok(()), None) => Ok(()),
    }
}

/// Rewrites the header of a single-part EXR of `chunk_count` chunks with the text attributes
/// `late` set and all attributes sorted by name.
///
/// The `exr` crate keeps custom attributes in a `HashMap`, so their order in the file (not
/// their values) changes from run to run. OpenEXR readers look attributes up by name, so the
/// order is free; sorting it makes equal images give byte-identical files. A late value of
/// another length than its placeholder moves the offset table and the chunks after it, and
/// every offset by as much: the file is then the one written with that value from the start.
fn finish_header(path: &Path, chunk_count: usize, late: &Late) -> std::io::Result<()> {
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
    let mut attributes: Vec<Vec<u8>> = Vec::new();
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
        let name = std::str::from_utf8(&head[at..name_end]).unwrap_or_default();
        match late.get(name) {
            Some(value) if &head[name_end + 1..type_end] == b"string" => {
                let mut a = head[at..size_at].to_vec();
                a.extend((value.len() as i32).to_le_bytes());
                a.extend(value.as_bytes());
                attributes.push(a);
            }
            Some(_) => return Err(bad("a late attribute is not a string")),
            None => attributes.push(head[at..end].to_vec()),
        }
        at = end;
    }
    // Sort by name (the bytes up to the first NUL).
    attributes.sort_by(|a, b| a.split(|&c| c == 0).next().cmp(&b.split(|&c| c == 0).next()));
    let sorted: Vec<u8> = attributes.concat();
    // The header's end (its terminating NUL) before and after; the offset table follows it.
    let (old_end, new_end) = (at as u64, 8 + sorted.len() as u64);
    if new_end != old_end {
        let len = file.metadata()?.len();
        let tail = old_end + 1;
        let mut buf = vec![0u8; 8 << 20];
        // Move the tail from its far end when it moves up the file, from its start otherwise,
        // so that no byte is overwritten before it is moved.
        let mut pieces: Vec<u64> = (tail..len).step_by(buf.len()).collect();
        if new_end > old_end {
            pieces.reverse();
        }
        for start in pieces {
            let n = (len - start).min(buf.len() as u64) as usize;
            file.seek(SeekFrom::Start(start))?;
            file.read_exact(&mut buf[..n])?;
            file.seek(SeekFrom::Start(start + new_end - old_end))?;
            file.write_all(&buf[..n])?;
        }
        file.set_len(len + new_end - old_end)?;
        let table = new_end + 1;
        let mut offsets = vec![0u8; chunk_count * 8];
        file.seek(SeekFrom::Start(table))?;
        file.read_exact(&mut offsets)?;
        for o in offsets.chunks_exact_mut(8) {
            let moved = u64::from_le_bytes(o.try_into().unwrap()) + new_end - old_end;
            o.copy_from_slice(&moved.to_le_bytes());
        }
        file.seek(SeekFrom::Start(table))?;
        file.write_all(&offsets)?;
    }
    file.seek(SeekFrom::Start(8))?;
    file.write_all(&sorted)?;
    file.write_all(&[0])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::exr_io::ExrChannels;

    fn channels(height: usize) -> ExrChannels {
        let (w, h) = (13, height);
        let mut ch = ExrChannels::new(w, h);
        for (k, name) in ["pt.b00.R", "A", "depth.Z", "crn.G", "R", "sum.pt.R.w3"].iter().enumerate() {
            ch.insert(*name, (0..w * h).map(|i| ((i * 7919 + k * 31) % 1013) as f32 * 0.37 - 40.0).collect());
        }
        ch.attributes.insert("cvtrace.spp".into(), AttrValue::Int(8));
        ch.attributes.insert("cvtrace.scene".into(), AttrValue::Text("场景/a.gltf".into()));
        ch.attributes.insert("cvtrace.nonFiniteSamples".into(), AttrValue::Text("0".into()));
        ch
    }

    /// `ch` with every plane random bits: blocks that do not compress, so are stored raw.
    fn with_noise(mut ch: ExrChannels) -> ExrChannels {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for plane in ch.channels.values_mut() {
            for v in plane.iter_mut() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                // Finite: bit 30 clear keeps the exponent below all ones.
                *v = f32::from_bits((state >> 32) as u32 & 0xBFFF_FFFF);
            }
        }
        ch
    }

    /// The `exr` crate's reader (not ours) decodes every block to the planes written: ZIP blocks
    /// and blocks stored raw, whole blocks, a short one and a short last one.
    #[test]
    fn the_blocks_decode_to_the_planes_written() {
        let dir = tempfile::tempdir().unwrap();
        for (h, noisy) in [(5, false), (32, false), (37, false), (37, true)] {
            let ch = if noisy { with_noise(channels(h)) } else { channels(h) };
            let p = dir.path().join(format!("blocks{h}{noisy}.exr"));
            ch.write(&p, false).unwrap();
            let raw = ch.width * h * ch.channels.len() * 4;
            if noisy {
                assert!(std::fs::metadata(&p).unwrap().len() as usize > raw, "random bits compressed");
            }
            let image = exr::prelude::read_all_flat_layers_from_file(&p).unwrap();
            let layer = &image.layer_data[0];
            assert_eq!(layer.encoding.compression, Compression::ZIP16);
            assert_eq!(layer.channel_data.list.len(), ch.channels.len());
            for c in &layer.channel_data.list {
                let plane: Vec<f32> = c.sample_data.values_as_f32().collect();
                let name = c.name.to_string();
                assert!(plane.iter().map(|v| v.to_bits()).eq(ch.channels[&name].iter().map(|v| v.to_bits())), "height {h}, {name}");
            }
        }
    }

    /// The predictor and deflate compress smooth data, and a block they cannot shrink is kept
    /// as it was (OpenEXR's rule for ZIP).
    #[test]
    fn a_block_is_compressed_only_where_that_makes_it_smaller() {
        let smooth: Vec<u8> = (0..4096).flat_map(|i| (1.0 + i as f32 * 1e-3).to_le_bytes()).collect();
        assert!(zip_block(smooth.clone()).len() < smooth.len() / 2);
        let mut state = 1u32;
        let noise: Vec<u8> = (0..4096)
            .map(|_| {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 24) as u8
            })
            .collect();
        assert_eq!(zip_block(noise.clone()), noise);
        assert_eq!(zip_block(Vec::new()), Vec::<u8>::new());
    }

    #[test]
    fn a_late_attribute_gives_the_file_written_with_it_from_the_start() {
        let dir = tempfile::tempdir().unwrap();
        for late in ["7", "123456789012", ""] {
            let ch = channels(37);
            let layout = ExrLayout::new(ch.width, ch.height, ch.channels.keys().cloned(), ch.attributes.clone());
            let planes: Vec<&[f32]> = ch.channels.values().map(Vec::as_slice).collect();
            let w = ch.width;
            let p = dir.path().join("late.exr");
            write_by_blocks(&p, true, &layout, |sink| -> Result<Late, StreamError> {
                // Band by band, as a renderer hands them over.
                for y0 in (0..ch.height).step_by(ROWS_PER_BLOCK) {
                    let rows = y0..(y0 + ROWS_PER_BLOCK).min(ch.height);
                    sink.put(rows, &|c, y, out| out.copy_from_slice(&planes[c][y * w..(y + 1) * w]))?;
                }
                Ok([("cvtrace.nonFiniteSamples".to_string(), late.to_string())].into())
            })
            .unwrap();
            let mut direct = ch.clone();
            direct.attributes.insert("cvtrace.nonFiniteSamples".into(), AttrValue::Text(late.into()));
            let from_the_start = dir.path().join("direct.exr");
            direct.write(&from_the_start, true).unwrap();
            assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&from_the_start).unwrap(), "late value {late:?}");
            assert_eq!(ExrChannels::read(&p).unwrap().attr("cvtrace.nonFiniteSamples"), Some(&AttrValue::Text(late.into())));
        }
    }

    #[test]
    fn an_error_of_the_producer_is_returned_and_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let ch = channels(20);
        let layout = ExrLayout::new(ch.width, ch.height, ch.channels.keys().cloned(), ch.attributes.clone());
        let p = dir.path().join("failed.exr");
        let e = write_by_blocks(&p, false, &layout, |_| -> Result<Late, StreamError> { Err(StreamError::invalid("x", "stopped")) })
            .unwrap_err();
        assert!(e.to_string().contains("stopped"), "{e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "a file was left behind");
    }
}
