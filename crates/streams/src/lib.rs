//! The contract between cvtrace's renderer and its reconstruction stage.
//!
//! A *stream file* is one single-part OpenEXR image holding two paired renders of the
//! same image: `pt` (independent random numbers per pixel) and `crn` (common random
//! numbers: sample `s` of every pixel uses the same random vector), each as the mean of
//! all its samples plus `B` batch means, and first-hit features. See `docs/stream-format.md`.
//!
//! The other files of a render live here too, so that what only reads or merges them needs no
//! renderer: the exact fixed-point sums every mean is made of ([`exact`]), a progressive
//! reference's sums ([`reference`](mod@reference)) and their checkpoints ([`checkpoint`]), and
//! the parts of a render split over machines with their merge ([`parts`]).
//!
//! Nothing here depends on Embree: any renderer can write these files, and the
//! reconstruction stage can read them.
#![forbid(unsafe_code)]

pub mod atomic;
mod attr;
pub mod block_writer;
pub mod checkpoint;
pub mod error;
pub mod exact;
pub mod exr_io;
pub mod iduw_layout;
pub mod image;
pub mod input_file;
pub mod output_lock;
pub mod parts;
pub mod preview;
pub mod provenance;
pub mod reference;
pub mod stream_set;

pub use error::{StreamError, SumsError};
pub use image::Image;
pub use provenance::Provenance;
pub use stream_set::{Features, Stream, StreamMeta, StreamSet};
