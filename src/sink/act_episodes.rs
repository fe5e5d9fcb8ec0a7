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

use std::path::{Path, PathBuf};

use hdf5::File;

use super::hdf5_native::{
    create_file, frames_dataset, group, new_dataset, FrameTarget, NativeHdf5Writer, NativeLayout,
    Rows, Run,
};
use super::SinkContext;
use crate::error::Result;
use crate::plan::ProfileChannel;
use crate::source::ChannelKind;

const QPOS: &str = "observations/qpos";
const QVEL: &str = "observations/qvel";

/// The `act_episodes` sink.
pub type ActEpisodesWriter = NativeHdf5Writer<ActEpisodes>;

/// ACT's layout: one file per episode.
pub struct ActEpisodes {
    dir: PathBuf,
    /// A channel is exported as `qvel`: no zeros are written in its place.
    has_qvel: bool,
}

fn episode_file(dir: &Path, e: usize) -> PathBuf {
    dir.join(format!("episode_{e}.hdf5"))
}

impl ActEpisodesWriter {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let channels = ctx.profile.channels.clone();
        let mut start = 0usize;
        for (e, &end) in ctx.episode_ends.iter().enumerate() {
            let len = end as usize - start;
            start = end as usize;
            let file = create_file(&episode_file(ctx.dir, e))?;
            file.new_attr::<bool>().create("sim")?.write_scalar(&true)?;
            let obs = group(&file, "observations")?;
            group(&obs, "images")?;
            for ch in channels.iter().filter(|c| c.kind == ChannelKind::Image) {
                frames_dataset(&file, &ch.array, len, &ch.shape)?;
            }
            file.close()?;
        }
        let layout = ActEpisodes {
            dir: ctx.dir.to_path_buf(),
            has_qvel: channels.iter().any(|c| c.array == QVEL),
        };
        Ok(NativeHdf5Writer::new(layout, ctx, channels))
    }
}

impl NativeLayout for ActEpisodes {
    fn data_file(&self) -> &str {
        crate::spec::OutputFormat::ActEpisodes.files().data
    }

    fn file_of(&self, e: usize) -> PathBuf {
        episode_file(&self.dir, e)
    }

    fn episode_group(&self, _: usize) -> String {
        "/".into()
    }

    fn frame_targets(&self, ch: &ProfileChannel, _: usize, run: Run) -> Vec<FrameTarget> {
        let Run { lo, n, .. } = run;
        vec![FrameTarget {
            path: ch.array.clone(),
            at: lo,
            from: 0,
            to: n,
        }]
    }

    /// Raw float32 values; `qvel` zeros beside `qpos` when no channel is exported as `qvel`.
    fn finish_episode(&self, file: &File, _: usize, len: usize, lowdim: &[Rows]) -> Result<()> {
        for (ch, values) in lowdim {
            let mut dims = vec![len];
            dims.extend(&ch.shape);
            new_dataset(file, &ch.array, &dims, values)?;
            if ch.array == QPOS && !self.has_qvel {
                new_dataset(file, QVEL, &dims, &vec![0.0f32; values.len()])?;
            }
        }
        Ok(())
    }
}
