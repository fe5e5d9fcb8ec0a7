//! robomimic's dataset layout (`format = "robomimic_hdf5"`): one `data.hdf5` that robomimic's
//! `SequenceDataset` opens directly, with every algorithm's configuration (the offline-RL and
//! hierarchical ones set `hdf5_load_next_obs = true`).
//!
//! ```text
//! data.hdf5
//!   /data  @total = sum of T, @env_args = '{"env_name": "", "type": 1, "env_kwargs": {}}'
//!   /data/demo_<i>          i = 0..E-1 in stored order, @num_samples = T
//!     actions               (T, A) float64 raw (the `action` channel)
//!     obs/<key>             (T, D) float64 raw, or (T, H, W, C) uint8 frames
//!     next_obs/<key>        the same arrays one step later: next_obs[t] = obs[t + 1], the last
//!                           step repeated (the episode ends there: `dones`)
//!     dones                 (T,) uint8, 1 at the last step
//!     rewards               (T,) float64 zeros
//!   /mask/train, /mask/valid  byte strings: the demo names of each split
//! ```
//! `<key>` is the channel's export name (`plan::export`): by default the source key it was read
//! from (`robot0_eef_pos` from a robomimic source's `obs/robot0_eef_pos`). Values are raw:
//! robomimic normalizes in its own code. Frames are stored twice (`obs` and `next_obs`), as
//! robomimic's own image datasets do. chunkc's loader does not read this format (there is no
//! window index in it).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use hdf5::types::{FixedAscii, VarLenUnicode};
use hdf5::{File, Group};

use super::{FrameEncoding, Frames, Sink, SinkContext, WindowIndex};
use crate::error::{Error, Result};
use crate::exec::LowdimStore;
use crate::plan::ProfileChannel;
use crate::source::ChannelKind;
use crate::stats::normalize::Normalizer;
use crate::window::EpisodeEnds;

pub const ROBOMIMIC_FILE: &str = "data.hdf5";
const ENV_ARGS: &str = r#"{"env_name": "", "type": 1, "env_kwargs": {}}"#;

pub struct RobomimicWriter {
    path: PathBuf,
    ends: EpisodeEnds,
    channels: Vec<Channel>,
    raw: Vec<Option<Arc<LowdimStore>>>,
}

fn group(parent: &Group, name: &str) -> Result<Group> {
    Ok(parent
        .create_group_builder()
        .obj_track_times(false)
        .create(name)?)
}

fn open_rw(path: &Path) -> Result<File> {
    File::open_rw(path).map_err(|e| Error::output(format!("cannot open {}: {e}", path.display())))
}

/// What the writer needs of a channel.
struct Channel {
    name: String,
    /// `data/demo_<i>/obs/<key>` or `data/demo_<i>/actions` (see `ProfileChannel::array`).
    array: ProfileChannel,
    /// The export name, when the channel is an observation (it then has `next_obs`).
    next_obs: Option<String>,
    shape: Vec<usize>,
    kind: ChannelKind,
}

impl Channel {
    fn obs(&self, e: usize) -> String {
        self.array.array_of(e)
    }

    fn next_obs(&self, e: usize) -> Option<String> {
        self.next_obs
            .as_ref()
            .map(|key| format!("data/{}/next_obs/{key}", demo(e)))
    }
}

fn demo(e: usize) -> String {
    format!("demo_{e}")
}

impl RobomimicWriter {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let channels: Vec<Channel> = ctx
            .profile
            .channels
            .iter()
            .map(|c| Channel {
                name: c.name.clone(),
                array: c.clone(),
                next_obs: c.export.clone().filter(|_| c.name != "action"),
                shape: c.shape.clone(),
                kind: c.kind,
            })
            .collect();
        let path = ctx.dir.join(ROBOMIMIC_FILE);
        let file = File::with_options()
            .with_fcpl(|p| p.obj_track_times(false))
            .create(&path)
            .map_err(|err| Error::output(format!("cannot create {}: {err}", path.display())))?;
        let data = group(&file, "data")?;
        let total = *ctx.episode_ends.last().unwrap_or(&0) as i64;
        data.new_attr::<i64>()
            .create("total")?
            .write_scalar(&total)?;
        let env_args = ENV_ARGS
            .parse::<VarLenUnicode>()
            .map_err(|e| Error::Internal(format!("env_args: {e}")))?;
        data.new_attr::<VarLenUnicode>()
            .create("env_args")?
            .write_scalar(&env_args)?;
        let mut start = 0usize;
        let (mut train, mut valid) = (Vec::new(), Vec::new());
        for (e, &end) in ctx.episode_ends.iter().enumerate() {
            let len = end as usize - start;
            start = end as usize;
            let g = group(&data, &demo(e))?;
            g.new_attr::<i64>()
                .create("num_samples")?
                .write_scalar(&(len as i64))?;
            group(&g, "obs")?;
            group(&g, "next_obs")?;
            for ch in channels.iter().filter(|c| c.kind == ChannelKind::Image) {
                let mut full = vec![len];
                full.extend(&ch.shape);
                let mut chunk = vec![1];
                chunk.extend(&ch.shape);
                for path in [Some(ch.obs(e)), ch.next_obs(e)].into_iter().flatten() {
                    file.new_dataset::<u8>()
                        .shape(full.clone())
                        .chunk(chunk.clone())
                        .obj_track_times(false)
                        .create(path.as_str())?;
                }
            }
            let name = FixedAscii::<32>::from_ascii(demo(e).as_bytes())
                .map_err(|err| Error::Internal(format!("demo name: {err}")))?;
            match ctx.profile.episodes.get(e).map(|ep| ep.split) {
                Some("val") => valid.push(name),
                _ => train.push(name),
            }
        }
        let mask = group(&file, "mask")?;
        for (key, names) in [("train", &train), ("valid", &valid)] {
            mask.new_dataset::<FixedAscii<32>>()
                .shape([names.len()])
                .obj_track_times(false)
                .create(key)?
                .write_raw(names)?;
        }
        file.close()?;
        Ok(RobomimicWriter {
            path,
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

impl Sink for RobomimicWriter {
    fn data_file(&self) -> &str {
        ROBOMIMIC_FILE
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
        let len = self.ends.len_of(e);
        let file = open_rw(&self.path)?;
        let ch = &self.channels[channel];
        let (lo, n) = (row - start, frames.len());
        let write = |path: &str, at: usize, from: usize, to: usize| -> Result<()> {
            if from == to {
                return Ok(());
            }
            let ds = file.dataset(path)?;
            let mut dims = vec![to - from];
            dims.extend(&ch.shape);
            let view =
                ndarray::ArrayViewD::from_shape(ndarray::IxDyn(&dims), frames.span(from, to))
                    .map_err(|err| Error::Internal(format!("frames of {}: {err}", ch.name)))?;
            let mut sel: Vec<hdf5::SliceOrIndex> = vec![(at..at + to - from).into()];
            sel.extend(ch.shape.iter().map(|&d| hdf5::SliceOrIndex::from(0..d)));
            ds.write_slice(view, hdf5::Hyperslab::from(sel))?;
            Ok(())
        };
        write(&ch.obs(e), lo, 0, n)?;
        if let Some(next) = ch.next_obs(e) {
            // Step s is the next observation of step s - 1; the last step is its own.
            match lo {
                0 => write(&next, 0, 1, n)?,
                _ => write(&next, lo - 1, 0, n)?,
            }
            if lo + n == len {
                write(&next, len - 1, n - 1, n)?;
            }
        }
        file.close()?;
        Ok(())
    }

    /// Raw values: robomimic normalizes in its own code.
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
        let file = open_rw(&self.path)?;
        let mut start = 0usize;
        for (e, &end) in self.ends.iter().enumerate() {
            let (lo, hi) = (start, end as usize);
            start = hi;
            let g = file.group(&format!("data/{}", demo(e)))?;
            for (ch, raw) in self.channels.iter().zip(&self.raw) {
                let (ChannelKind::Lowdim, Some(raw)) = (ch.kind, raw) else {
                    continue;
                };
                let values: Vec<f64> = raw.rows(lo, hi)?.iter().map(|&v| f64::from(v)).collect();
                let mut dims = vec![hi - lo];
                dims.extend(&ch.shape);
                let write = |path: &str, values: &[f64]| -> Result<()> {
                    file.new_dataset::<f64>()
                        .shape(dims.clone())
                        .obj_track_times(false)
                        .create(path)?
                        .write_raw(values)?;
                    Ok(())
                };
                write(&ch.obs(e), &values)?;
                if let Some(next) = ch.next_obs(e) {
                    let width = values.len() / (hi - lo).max(1);
                    let mut shifted = values[width.min(values.len())..].to_vec();
                    shifted.extend_from_slice(&values[values.len() - width..]);
                    write(&next, &shifted)?;
                }
            }
            let len = hi - lo;
            let mut dones = vec![0u8; len];
            if let Some(last) = dones.last_mut() {
                *last = 1;
            }
            g.new_dataset::<u8>()
                .shape([len])
                .obj_track_times(false)
                .create("dones")?
                .write_raw(&dones)?;
            g.new_dataset::<f64>()
                .shape([len])
                .obj_track_times(false)
                .create("rewards")?
                .write_raw(&vec![0.0f64; len])?;
        }
        file.close()?;
        Ok(())
    }
}
