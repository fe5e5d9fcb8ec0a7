//! The keys of how image frames are stored: `image_compression` and its `image_compression_level`
//! and `image_quality` (HDF5 only), `image_encoding` (Parquet only), and the `video_*` encoder
//! keys of either video storage, with a chunkc that can encode video.

use super::Checker;
use crate::spec::model::{ImageCompression, OutputFormat, VideoCodec};
use crate::spec::preset::{Profile, HAS_X264};

/// The encoder keys of `image_encoding = "video"` and `image_compression = "video"`.
const ENCODER_KEYS: [&str; 4] = ["video_codec", "video_crf", "video_gop", "video_copy"];

impl Checker<'_> {
    /// `image_compression` and its level and quality: only the HDF5 layouts store frames that
    /// way; the level is gzip's, the quality JPEG's.
    pub(super) fn image_options(&mut self, name: &str, p: &Profile) {
        let key = |k: &'static str| ["profiles", name, k];
        let set = |k: &str| p.origins.get(k).is_some_and(|o| o != "default");
        if p.format != OutputFormat::Hdf5 {
            let how = match p.format {
                OutputFormat::Zarr => "compresses frames with `compression`",
                OutputFormat::Parquet => "stores frames as `image_encoding` says",
                _ => "stores frames uncompressed, as its codebase does",
            };
            for k in [
                "image_compression",
                "image_compression_level",
                "image_quality",
            ] {
                if set(k) {
                    let message = format!(
                        "`{k}` needs `format = \"hdf5\"`; profile `{name}` writes `{}`, which {how}",
                        p.format.name()
                    );
                    self.value(&key(k), message, "only for hdf5", None);
                }
            }
            return;
        }
        let compression = p.image_compression;
        if let Some(level) = p.image_compression_level {
            if compression != ImageCompression::Gzip {
                let message = format!(
                    "`image_compression = \"{}\"` takes no `image_compression_level`",
                    compression.name()
                );
                let help = Some("set `image_compression = \"gzip\"` to compress frames".into());
                let at = key("image_compression_level");
                self.value(&at, message, "has no level", help);
            } else if level > 9 {
                let message =
                    format!("`image_compression_level` {level} is out of range for gzip (0..=9)");
                let at = key("image_compression_level");
                self.value(&at, message, "out of range", None);
            }
        }
        if let Some(quality) = p.image_quality {
            if compression != ImageCompression::Jpeg {
                let message = format!(
                    "`profiles.{name}.image_quality` is JPEG's quality, and `image_compression` \
                     is `{}`",
                    compression.name()
                );
                let help = Some("set `image_compression = \"jpeg\"`".into());
                self.value(&key("image_quality"), message, "only for jpeg", help);
            } else if !(1..=100).contains(&quality) {
                let message =
                    format!("`profiles.{name}.image_quality` {quality} is out of range (1..=100)");
                self.value(&key("image_quality"), message, "out of range", None);
            }
        }
        if compression == ImageCompression::Video && !cfg!(feature = "video") {
            let message = format!(
                "`profiles.{name}.image_compression = \"video\"` needs a chunkc built with the \
                 `video` cargo feature (`cargo build --release --features video`); this one was \
                 built without it"
            );
            let help = Some("or store frames as `jpeg`, which needs no FFmpeg".into());
            self.value(
                &key("image_compression"),
                message,
                "not in this build",
                help,
            );
        }
    }

    /// `image_encoding` (parquet only) and the `video_*` keys: only for a profile that stores
    /// video (`image_encoding = "video"` or `image_compression = "video"`), values in the
    /// encoder's range, and a chunkc that can encode.
    pub(super) fn video_options(&mut self, name: &str, p: &Profile) {
        let key = |k: &'static str| ["profiles", name, k];
        let set = |k: &str| p.origins.contains_key(k);
        if p.format != OutputFormat::Parquet && set("image_encoding") {
            let message = format!(
                "`image_encoding` needs `format = \"parquet\"`; profile `{name}` writes `{}`",
                p.format.name()
            );
            self.value(&key("image_encoding"), message, "only for parquet", None);
        }
        let Some(video) = p.video() else {
            let (how, help) = match p.format {
                OutputFormat::Parquet => ("stores frames as PNG", "image_encoding"),
                OutputFormat::Hdf5 => ("stores no video", "image_compression"),
                _ => ("stores no video", ""),
            };
            for k in ENCODER_KEYS.into_iter().filter(|k| set(k)) {
                let message = format!("`{k}` sets the video encoder, but profile `{name}` {how}");
                let help = (!help.is_empty())
                    .then(|| format!("set `{help} = \"video\"` to store frames as video"));
                self.value(&key(k), message, "only for video", help);
            }
            return;
        };
        if p.format == OutputFormat::Parquet && !cfg!(feature = "video") {
            let message =
                "`image_encoding = \"video\"` needs a chunkc built with the `video` cargo \
                           feature (`cargo build --release --features video`); this one was built \
                           without it"
                    .to_string();
            let help = Some("or keep `image_encoding = \"png\"`".into());
            self.value(&key("image_encoding"), message, "not in this build", help);
        }
        if video.codec == VideoCodec::Libx264 && !HAS_X264 {
            let message = format!(
                "`profiles.{name}.video_codec = \"libx264\"`: this chunkc (the wheel) links an \
                 LGPL FFmpeg without x264, which is GPL; its encoder is `libsvtav1`"
            );
            let help = Some(
                "use `video_codec = \"libsvtav1\"` (or leave it out), or a chunkc built from \
                 source against a system FFmpeg with x264 (book: Install)"
                    .into(),
            );
            self.value(&key("video_codec"), message, "not in this build", help);
        }
        if video.crf > video.codec.max_crf() {
            let message = format!(
                "`video_crf` {} is out of range for {} (0..={})",
                video.crf,
                video.codec.name(),
                video.codec.max_crf()
            );
            self.value(&key("video_crf"), message, "out of range", None);
        }
        if video.gop == 0 {
            let message = "`video_gop` must be at least 1 (1: every frame a keyframe)".to_string();
            self.value(&key("video_gop"), message, "must be >= 1", None);
        }
    }
}
