//! From paths to images: [`driver`] renders the paired streams and progressive references over
//! parallel tiles ([`tiles`]), and [`stream_file`] writes a stream render, or a part of one,
//! into its file band by band as it renders.
pub mod driver;
pub mod stream_file;
pub mod tiles;
