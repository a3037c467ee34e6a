//! Borrowed views of row-major images with interleaved channels.

use crate::error::{CoreError, Result};

/// A read-only view of a contiguous `height x width x channels` image.
#[derive(Debug, Clone, Copy)]
pub struct ImageView<'a, T> {
    data: &'a [T],
    width: usize,
    height: usize,
    channels: usize,
}

impl<'a, T: Copy> ImageView<'a, T> {
    /// Wraps `data` (C-order, interleaved) after checking that its length matches the shape.
    pub fn new(
        data: &'a [T],
        height: usize,
        width: usize,
        channels: usize,
        name: &'static str,
    ) -> Result<Self> {
        if height == 0 || width == 0 {
            return Err(CoreError::invalid(
                name,
                format!("image must be at least 1x1 pixels; got {height}x{width}"),
            ));
        }
        if channels == 0 {
            return Err(CoreError::invalid(
                name,
                "image must have at least one channel",
            ));
        }
        let expected = height
            .checked_mul(width)
            .and_then(|n| n.checked_mul(channels))
            .ok_or_else(|| CoreError::invalid(name, "image dimensions overflow"))?;
        if data.len() != expected {
            return Err(CoreError::invalid(
                name,
                format!(
                    "buffer holds {} values but {height}x{width}x{channels} needs {expected}",
                    data.len()
                ),
            ));
        }
        Ok(Self {
            data,
            width,
            height,
            channels,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Interleaved channels per pixel.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The whole buffer, row-major.
    pub fn data(&self) -> &'a [T] {
        self.data
    }

    /// One row (all channels interleaved).
    pub fn row(&self, y: usize) -> &'a [T] {
        let stride = self.width * self.channels;
        &self.data[y * stride..(y + 1) * stride]
    }
}
