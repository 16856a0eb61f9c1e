//! Parts of a render, made on any machine and merged into exactly the file one render writes.
//!
//! A part of a stream render is a contiguous range of whole batches (both streams); a part of
//! a reference a contiguous range of whole passes. A part stores what its range contributes
//! and nothing that depends on the others: the batch means of its batches (a batch never
//! straddles two parts, so they are the one-shot render's bit for bit) and the exact sums of
//! its samples ([`crate::exact`]), which add up to the one-shot render's sums in any order.
//! The merge adds the sums, divides by the sample count and writes the file with the same
//! code as the one-shot render. docs/stream-format.md ("Parts") describes the files.
//!
//! [`spec`]: `--part I/N` and the errors of parts; [`header`]: what a part's header records;
//! [`stream`] and [`reference`](mod@reference): the parts of the two kinds of render and the
//! whole files they add up to; [`merge`](mod@merge): the check that parts make one render, and
//! their merge.
pub mod header;
pub mod merge;
pub mod reference;
pub mod spec;
pub mod stream;

pub use header::{PartHeader, ATTR_END, ATTR_FIRST, ATTR_OF, KIND_ATTR, REFERENCE_KIND, STREAMS_KIND};
pub use merge::{check_parts, merge, Merged};
pub use reference::{write_reference, write_reference_part};
pub use spec::{PartError, PartSpec};
pub use stream::{stream_file_exr, write_stream_file, StreamPart, StreamSums};
