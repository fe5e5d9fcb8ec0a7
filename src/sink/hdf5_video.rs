//! `image_compression = "video"` in chunkc's HDF5 layout: one mp4 per episode and camera beside
//! the data file, which names each episode's file and frame count.
//!
//! ```text
//! videos/<camera>/episode_<id:06>.mp4     yuv420p, a keyframe every `video_gop` frames,
//!                                         frame i at time i / fps
//! /videos/<camera>/path    (E,) str       each stored episode's file, relative to the profile
//! /videos/<camera>/frames  (E,) int64     its frame count (= the episode's stored steps)
//! /videos/<camera>/copied  (E,) uint8     1 where the file is the source video's own packets
//!     attrs: encoding = "video", codec, crf, gop, pix_fmt, frame_shape = [H, W, 3]
//!            (the encoder's; a copied file keeps the source's codec and pixel format: when
//!            every file is copied, codec is the source's, crf and gop -1), stored = "copied" |
//!            "encoded" | "mixed", copy_refused (why copies were refused, when any was)
//! ```
//! Where the episode's frames are a source video's own, unchanged, its packets are copied
//! ([`super::video_copy`], `video_copy`); otherwise each file is encoded on a thread of its own
//! with a single-threaded encoder ([`super::video_encode`]): [`super::video_episodes`] does
//! either.

use std::path::Path;

use hdf5::types::VarLenUnicode;
use hdf5::{Dataset, Group};

use super::video_encode::{codec_name, StreamShape, PIX_FMT};
pub(super) use super::video_episodes::Encoders;
use super::video_episodes::EpisodeCamera;
use super::video_info::StoredVideo;
use crate::error::{Error, Result};
use crate::spec::VideoSettings;

/// The file of episode `id`'s frames of `camera`, relative to the profile directory.
pub fn episode_path(camera: &str, id: u64) -> String {
    format!("videos/{camera}/episode_{id:06}.mp4")
}

/// What a built `data.h5` records of one video camera's files: how many episodes were copied
/// from the source's stream, of how many, and why the others were not (`copy_refused`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CopyRecord {
    pub camera: String,
    pub copied: usize,
    pub episodes: usize,
    pub refused: Option<String>,
}

/// Every video camera's [`CopyRecord`] in a built `data.h5` (none without video storage).
pub fn copy_records(data_file: &Path) -> Result<Vec<CopyRecord>> {
    let file = hdf5::File::open(data_file)
        .map_err(|e| Error::output(format!("cannot open {}: {e}", data_file.display())))?;
    let Ok(videos) = file.group("videos") else {
        return Ok(Vec::new());
    };
    let mut records = Vec::new();
    for camera in videos.member_names()? {
        let group = videos.group(&camera)?;
        let copied: Vec<u8> = group.dataset("copied")?.read_raw()?;
        let refused = match group.attr("copy_refused") {
            Ok(a) => Some(a.read_scalar::<VarLenUnicode>()?.to_string()),
            Err(_) => None,
        };
        records.push(CopyRecord {
            camera,
            copied: copied.iter().filter(|&&c| c != 0).count(),
            episodes: copied.len(),
            refused,
        });
    }
    Ok(records)
}

/// One camera's per-episode videos.
pub(super) struct VideoChannel {
    pub(super) camera: EpisodeCamera,
    frames: Dataset,
    copied: Dataset,
}

fn text(s: &str) -> Result<VarLenUnicode> {
    s.parse::<VarLenUnicode>()
        .map_err(|e| Error::Internal(format!("text {s:?}: {e}")))
}

/// The attributes of `/videos/<camera>`: how its files were encoded.
fn describe(group: &Group, settings: VideoSettings, shape: &[usize]) -> Result<()> {
    // `codec` and `pix_fmt` as the encoder writes them, until the files are written
    // ([`VideoChannel::record_copies`] sets what they hold).
    let attrs: [(&str, String); 4] = [
        ("encoding", "video".into()),
        ("codec", codec_name(settings.codec).into()),
        ("pix_fmt", PIX_FMT.into()),
        ("encoder", settings.codec.name().into()),
    ];
    for (k, v) in attrs {
        group
            .new_attr::<VarLenUnicode>()
            .create(k)?
            .write_scalar(&text(&v)?)?;
    }
    for (k, v) in [("crf", settings.crf), ("gop", settings.gop)] {
        group
            .new_attr::<i64>()
            .create(k)?
            .write_scalar(&i64::from(v))?;
    }
    let dims: Vec<i64> = shape.iter().map(|&d| d as i64).collect();
    group
        .new_attr::<i64>()
        .shape([3])
        .create("frame_shape")?
        .write_raw(&dims)?;
    Ok(())
}

impl VideoChannel {
    /// Creates `/videos/<camera>` for the stored episodes (`ends`, `ids`) and the camera's
    /// directory under `dir`.
    pub(super) fn create(
        root: &Group,
        dir: &Path,
        name: &str,
        shape: &[usize],
        fps: f64,
        settings: VideoSettings,
        (ends, ids): (&[u64], &[u64]),
    ) -> Result<Self> {
        let [height, width, 3] = *shape else {
            return Err(Error::output(format!(
                "channel `{name}`: `image_compression = \"video\"` stores (height, width, 3) RGB \
                 frames, and this channel's frames are {shape:?}; use `image_compression = \"jpeg\"`"
            )));
        };
        let videos = dir.join("videos").join(name);
        std::fs::create_dir_all(&videos)
            .map_err(|e| Error::output(format!("cannot create {}: {e}", videos.display())))?;
        let top = match root.group("videos") {
            Ok(g) => g,
            Err(_) => root
                .create_group_builder()
                .obj_track_times(false)
                .create("videos")?,
        };
        let group = top
            .create_group_builder()
            .obj_track_times(false)
            .create(name)?;
        let paths: Vec<VarLenUnicode> = ids
            .iter()
            .map(|&id| text(&episode_path(name, id)))
            .collect::<Result<_>>()?;
        group
            .new_dataset::<VarLenUnicode>()
            .shape([paths.len()])
            .obj_track_times(false)
            .create("path")?
            .write_raw(&paths)?;
        let counts: Vec<i64> = ends
            .iter()
            .scan(0u64, |start, &end| {
                let n = end - *start;
                *start = end;
                Some(n as i64)
            })
            .collect();
        let frames = group
            .new_dataset::<i64>()
            .shape([counts.len()])
            .obj_track_times(false)
            .create("frames")?;
        frames.write_raw(&counts)?;
        let copied = group
            .new_dataset::<u8>()
            .shape([counts.len()])
            .obj_track_times(false)
            .create("copied")?;
        describe(&group, settings, shape)?;
        Ok(VideoChannel {
            camera: EpisodeCamera {
                name: name.to_string(),
                shape: StreamShape { height, width, fps },
                settings,
            },
            frames,
            copied,
        })
    }

    /// Writes `/videos/<camera>/copied`: per stored episode, whether its file was copied; and
    /// sets the group's `codec`, `profile` and `pix_fmt` to what the files hold (`mixed` where
    /// they differ; no `profile` where a stream names none), and `crf` and `gop` to -1 when every
    /// file was copied (nothing was encoded).
    pub(super) fn record_copies(
        &self,
        copied: &[u8],
        stored: &StoredVideo,
        refused: &[String],
    ) -> Result<()> {
        self.copied.write_raw(copied)?;
        let group = self
            .copied
            .file()?
            .group(&format!("videos/{}", self.camera.name))?;
        let set = |name: &str, value: &str| -> Result<()> {
            match group.attr(name) {
                Ok(a) => a.write_scalar(&text(value)?)?,
                Err(_) => group
                    .new_attr::<VarLenUnicode>()
                    .create(name)?
                    .write_scalar(&text(value)?)?,
            }
            Ok(())
        };
        set("stored", stored.stored())?;
        if !refused.is_empty() {
            set("copy_refused", &refused.join("; "))?;
        }
        if !stored.formats.is_empty() {
            let mixed = || "mixed".to_string();
            set(
                "codec",
                &stored.shared(|f| f.codec.clone()).unwrap_or_else(mixed),
            )?;
            set(
                "pix_fmt",
                &stored.shared(|f| f.pix_fmt.clone()).unwrap_or_else(mixed),
            )?;
            match stored.shared(|f| f.profile.clone()) {
                Some(Some(profile)) => set("profile", &profile)?,
                Some(None) => {}
                None => set("profile", "mixed")?,
            }
        }
        if stored.stored() == "copied" {
            group.attr("crf")?.write_scalar(&-1i64)?;
            group.attr("gop")?.write_scalar(&-1i64)?;
        }
        Ok(())
    }

    /// The camera's name.
    pub(super) fn name(&self) -> &str {
        &self.camera.name
    }

    /// The dataset `/videos/<camera>/frames`.
    pub(super) fn dataset(&self) -> Dataset {
        self.frames.clone()
    }
}
