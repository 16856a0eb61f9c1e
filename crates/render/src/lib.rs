//! cvtrace's path tracer (work in progress).
pub mod intersect;
pub use intersect::{Hit, Intersector, Ray};
