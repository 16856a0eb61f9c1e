//! Rendering a stream file, or a part of one, straight into the file, band by band.
//!
//! A stream file holds far more samples than its compressed size (a 1920×1080 file of 16
//! batches: 113 channels, 0.94 GB of f32 samples, about a third of that on disk), so holding
//! the whole image, let alone copies of it, costs several times the file. Every band of a
//! [`StreamRender`] is final once rendered: it becomes the file's channels for its rows, with
//! the code that writes a whole file ([`cvtrace_streams::parts::stream_file_exr`],
//! [`StreamPart::to_exr`]), is compressed while the next band renders, written, and dropped.
//! The file is the one the whole-image writers make, byte for byte.
use crate::error::RenderError;
use crate::film::driver::StreamRender;
use crate::intersect::Intersector;
use cvtrace_streams::block_writer::{write_by_blocks, BlockSink, ExrLayout, Late};
use cvtrace_streams::exr_io::{AttrValue, ExrChannels};
use cvtrace_streams::parts::{stream_file_exr, PartSpec, StreamPart};
use cvtrace_streams::{Provenance, StreamError};
use std::ops::Range;
use std::path::Path;
use std::time::{Duration, Instant};

const ATTR_NON_FINITE: &str = "cvtrace.nonFiniteSamples";

// A band (a row of tiles) must be whole blocks of the file, but for the image's last.
const _: () = assert!((crate::film::tiles::TILE_SIZE as usize).is_multiple_of(cvtrace_streams::block_writer::ROWS_PER_BLOCK));

/// What [`render_to_file`] did.
#[derive(Clone, Copy, Debug)]
pub struct Written {
    /// Samples that were NaN or infinite, replaced by zero.
    pub non_finite: u64,
    /// From the end of the last band's rendering to the finished file.
    pub tail: Duration,
}

/// Renders `render` into `path` atomically: the stream file of `provenance`'s render, or with
/// `part` that part's file (the render's batches must then be the part's).
pub fn render_to_file<T: Intersector>(
    render: &StreamRender<'_, T>,
    path: &Path,
    provenance: &Provenance,
    scene: &str,
    part: Option<PartSpec>,
    overwrite: bool,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Written, RenderError> {
    let settings = render.settings();
    let to_exr = |band: StreamPart| -> Result<ExrChannels, StreamError> {
        match part {
            Some(of) => Ok(band.to_exr(provenance, scene, of)),
            None => {
                let mut set = band.into_stream_set(settings.seed, settings.max_depth).expect("a render of every batch");
                set.meta.scene = scene.to_string();
                stream_file_exr(path, &set, provenance)
            }
        }
    };
    let mut bands = render.bands();
    let rows = bands.next().expect("an image has at least one band");
    let band = render.render_band(rows.clone(), progress);
    let mut non_finite = band.non_finite;
    let first = to_exr(band)?;
    // The header is written before the other bands are rendered: the count of replaced
    // samples is set once they all are.
    let mut attributes = first.attributes.clone();
    attributes.insert(ATTR_NON_FINITE.into(), AttrValue::Text("0".into()));
    let layout = ExrLayout::new(first.width, settings.height as usize, first.channels.keys().cloned(), attributes);
    let mut tail = Duration::ZERO;
    write_by_blocks(path, overwrite, &layout, |sink: &mut BlockSink<'_>| -> Result<Late, RenderError> {
        let mut pending = (rows, first);
        for rows in bands {
            let (compressed, band) = rayon::join(|| compress(sink, &layout, &pending), || render.render_band(rows.clone(), progress));
            sink.write(compressed?)?;
            non_finite += band.non_finite;
            pending = (rows, to_exr(band)?);
        }
        let done = Instant::now();
        let last = compress(sink, &layout, &pending)?;
        sink.write(last)?;
        tail = done.elapsed();
        Ok([(ATTR_NON_FINITE.to_string(), non_finite.to_string())].into())
    })?;
    if non_finite > 0 {
        tracing::warn!("{non_finite} samples were NaN or infinite and were replaced by zero");
    }
    Ok(Written { non_finite, tail })
}

/// Compresses the rows of one band from its channels.
fn compress(
    sink: &BlockSink<'_>,
    layout: &ExrLayout,
    (rows, band): &(Range<usize>, ExrChannels),
) -> Result<cvtrace_streams::block_writer::CompressedBlocks, StreamError> {
    assert!(band.channels.keys().eq(layout.channels.iter()), "a band has other channels than the file");
    let planes: Vec<&[f32]> = band.channels.values().map(Vec::as_slice).collect();
    let w = band.width;
    let y0 = rows.start;
    sink.compress(rows.clone(), &|c, y, out| out.copy_from_slice(&planes[c][(y - y0) * w..(y - y0 + 1) * w]))
}
