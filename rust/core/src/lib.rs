//! Pure-Rust algorithms of tacswitch.
//!
//! Conventions shared by every module:
//! - images are row-major, interleaved channels (OpenCV/numpy `H x W x C` C-order), colour order **BGR**;
//! - points are `(x, y)` in pixels with pixel centres at integer coordinates;
//! - motions are `(dx, dy)` aligned with the reference points; lost markers are NaN and flagged invalid.
//!
//! Nothing here knows about Python; the bindings crate validates and converts, then calls in.

pub mod biharmonic;
pub mod error;
pub mod extract;
pub mod geometry;
pub mod image;
pub mod kdtree;
pub mod mask_grow;
pub mod matching;
pub mod merge;
mod simd;
pub mod slip;
pub mod slip_features;
pub mod still_filter;
pub mod telea;
pub mod tracker;

pub use error::{CoreError, Result};
