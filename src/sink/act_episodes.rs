//! ACT's own layout (`format = "act_episodes"`): one `episode_<i>.hdf5` per stored episode,
//! `i` = 0..E-1 in stored order (ACT's `load_data` needs contiguous ids from 0).
//!
//! ```text
//! episode_<i>.hdf5
//!   @sim = True                      actions start at the observation's step (chunkc's
//!                                    `current` alignment)
//!   /action                (T, A) float32 raw
//!   /observations/qpos     (T, D) float32 raw (the state channel; see `plan::export`)
//!   /observations/qvel     (T, D) float32: a channel exported as `qvel` (an ALOHA source's
//!                          `observations/qvel`), else zeros (ACT reads it but never uses it)
//!   /observations/<key>    (T, D) float32 raw, every other low-dim observation
//!   /observations/images/<cam>  (T, H, W, C) uint8, one frame per chunk, uncompressed
//! ```
//! `<key>` and `<cam>` are export names (`plan::export`): by default the last component of the
//! source key, so an ALOHA source's `observations/images/top` is camera `top` again, as ACT's
//! `camera_names` expect. Values are raw: ACT normalizes with `dataset_stats.pkl`, written beside
//! the episodes (the `act` statistics format is always on for this format).

use std::path::PathBuf;
use std::sync::Arc;

use hdf5::{File, Group};

use super::{FrameEncoding, Frames, Sink, SinkContext, WindowIndex};
use crate::error::{Error, Result};
use crate::exec::LowdimStore;
use crate::plan::ProfileChannel;
use crate::source::ChannelKind;
use crate::stats::normalize::Normalizer;
use crate::window::EpisodeEnds;

const QPOS: &str = "observations/qpos";
const QVEL: &str = "observations/qvel";

pub struct ActEpisodesWriter {
    dir: PathBuf,
    ends: EpisodeEnds,
    channels: Vec<ProfileChannel>,
    raw: Vec<Option<Arc<LowdimStore>>>,
}

fn episode_file(dir: &std::path::Path, e: usize) -> PathBuf {
    dir.join(format!("episode_{e}.hdf5"))
}

fn group(parent: &Group, name: &str) -> Result<Group> {
    Ok(parent
        .create_group_builder()
        .obj_track_times(false)
        .create(name)?)
}

fn open_rw(path: &std::path::Path) -> Result<File> {
    File::open_rw(path).map_err(|e| Error::output(format!("cannot open {}: {e}", path.display())))
}

impl ActEpisodesWriter {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let channels = ctx.profile.channels.clone();
        let mut start = 0usize;
        for (e, &end) in ctx.episode_ends.iter().enumerate() {
            let len = end as usize - start;
            start = end as usize;
            let path = episode_file(ctx.dir, e);
            let file = File::with_options()
                .with_fcpl(|p| p.obj_track_times(false))
                .create(&path)
                .map_err(|err| Error::output(format!("cannot create {}: {err}", path.display())))?;
            file.new_attr::<bool>().create("sim")?.write_scalar(&true)?;
            let obs = group(&file, "observations")?;
            group(&obs, "images")?;
            for ch in channels.iter().filter(|c| c.kind == ChannelKind::Image) {
                let mut full = vec![len];
                full.extend(&ch.shape);
                let mut chunk = vec![1];
                chunk.extend(&ch.shape);
                file.new_dataset::<u8>()
                    .shape(full)
                    .chunk(chunk)
                    .obj_track_times(false)
                    .create(ch.array.as_str())?;
            }
            file.close()?;
        }
        Ok(ActEpisodesWriter {
            dir: ctx.dir.to_path_buf(),
            ends: ctx.episode_ends.into(),
            raw: channels.iter().map(|_| None).collect(),
            channels,
        })
    }

    fn episode_of(&self, row: usize) -> (usize, usize) {
        let e = self.ends.partition_point(|&end| end as usize <= row);
        (e, self.ends.start(e))
    }
}

impl Sink for ActEpisodesWriter {
    fn data_file(&self) -> &str {
        "episode_0.hdf5"
    }

    fn frame_encoding(&self) -> FrameEncoding {
        FrameEncoding::Raw
    }

    fn stores_normalized(&self) -> bool {
        false
    }

    fn write_frames(&mut self, channel: usize, row: usize, frames: &Frames) -> Result<()> {
        if frames.is_empty() {
            return Ok(());
        }
        let (e, start) = self.episode_of(row);
        let file = open_rw(&episode_file(&self.dir, e))?;
        let ch = &self.channels[channel];
        let ds = file.dataset(&ch.array)?;
        let mut dims = vec![frames.len()];
        dims.extend(&ch.shape);
        let view = ndarray::ArrayViewD::from_shape(ndarray::IxDyn(&dims), frames.bytes())
            .map_err(|err| Error::Internal(format!("frames of {}: {err}", ch.name)))?;
        let mut sel: Vec<hdf5::SliceOrIndex> =
            vec![(row - start..row - start + frames.len()).into()];
        sel.extend(ch.shape.iter().map(|&d| hdf5::SliceOrIndex::from(0..d)));
        ds.write_slice(view, hdf5::Hyperslab::from(sel))?;
        file.close()?;
        Ok(())
    }

    /// Raw values: ACT normalizes with `dataset_stats.pkl`.
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        _: &Normalizer,
    ) -> Result<()> {
        self.raw[channel] = Some(Arc::clone(raw));
        Ok(())
    }

    fn write_index(&mut self, _: &dyn WindowIndex) -> Result<()> {
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<()> {
        let has_qvel = self.channels.iter().any(|c| c.array == QVEL);
        let mut start = 0usize;
        for (e, &end) in self.ends.iter().enumerate() {
            let (lo, hi) = (start, end as usize);
            start = hi;
            let file = open_rw(&episode_file(&self.dir, e))?;
            for (ch, raw) in self.channels.iter().zip(&self.raw) {
                let (ChannelKind::Lowdim, Some(raw)) = (ch.kind, raw) else {
                    continue;
                };
                let values = raw.rows(lo, hi)?;
                let mut dims = vec![hi - lo];
                dims.extend(&ch.shape);
                let write = |path: &str, values: &[f32]| -> Result<()> {
                    file.new_dataset::<f32>()
                        .shape(dims.clone())
                        .obj_track_times(false)
                        .create(path)?
                        .write_raw(values)?;
                    Ok(())
                };
                write(&ch.array, &values)?;
                if ch.array == QPOS && !has_qvel {
                    write(QVEL, &vec![0.0; values.len()])?;
                }
            }
            file.close()?;
        }
        Ok(())
    }
}
