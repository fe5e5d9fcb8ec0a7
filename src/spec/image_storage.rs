//! How chunkc's HDF5 layout stores camera frames (`image_compression`), and the defaults of its
//! lossy encodings. Spec types only (serde + schemars), like `model`.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// JPEG quality of `image_compression = "jpeg"` when the spec gives none: visually lossless for
/// camera frames, about 10x smaller than raw.
pub const DEFAULT_IMAGE_QUALITY: u32 = 90;

/// How the HDF5 layouts store image frames (see `image_compression`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ImageCompression {
    /// One frame per chunk, uncompressed.
    None,
    /// One frame per chunk, deflate (HDF5's gzip filter).
    Gzip,
    /// One JPEG per frame (libjpeg-turbo at `image_quality`), back to back in `/data/<camera>`.
    Jpeg,
    /// One mp4 per episode and camera, `videos/<camera>/episode_<id>.mp4`.
    Video,
}

impl ImageCompression {
    pub fn name(self) -> &'static str {
        match self {
            ImageCompression::None => "none",
            ImageCompression::Gzip => "gzip",
            ImageCompression::Jpeg => "jpeg",
            ImageCompression::Video => "video",
        }
    }
}
