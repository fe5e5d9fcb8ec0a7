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

use std::path::PathBuf;

use hdf5::types::{FixedAscii, VarLenUnicode};
use hdf5::File;

use super::hdf5_native::{
    create_file, frames_dataset, group, new_dataset, FrameTarget, NativeHdf5Writer, NativeLayout,
    Rows, Run,
};
use super::SinkContext;
use crate::error::{Error, Result};
use crate::plan::ProfileChannel;
use crate::source::ChannelKind;

pub const ROBOMIMIC_FILE: &str = crate::spec::OutputFormat::RobomimicHdf5.files().data;
const ENV_ARGS: &str = r#"{"env_name": "", "type": 1, "env_kwargs": {}}"#;

/// The `robomimic_hdf5` sink.
pub type RobomimicWriter = NativeHdf5Writer<Robomimic>;

/// robomimic's layout: every episode a `data/demo_<i>` group of one file.
pub struct Robomimic {
    path: PathBuf,
}

/// `data/demo_<i>/next_obs/<key>` of an observation channel (`None` for the action).
fn next_obs(ch: &ProfileChannel, e: usize) -> Option<String> {
    ch.export
        .as_ref()
        .filter(|_| ch.name != "action")
        .map(|key| format!("data/{}/next_obs/{key}", demo(e)))
}

fn demo(e: usize) -> String {
    format!("demo_{e}")
}

impl RobomimicWriter {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let channels = ctx.profile.channels.clone();
        let path = ctx.dir.join(ROBOMIMIC_FILE);
        let file = create_file(&path)?;
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
                for path in [Some(ch.array_of(e)), next_obs(ch, e)]
                    .into_iter()
                    .flatten()
                {
                    frames_dataset(&file, &path, len, &ch.shape)?;
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
            new_dataset(&mask, key, &[names.len()], names)?;
        }
        file.close()?;
        Ok(NativeHdf5Writer::new(Robomimic { path }, ctx, channels))
    }
}

impl NativeLayout for Robomimic {
    fn data_file(&self) -> &str {
        ROBOMIMIC_FILE
    }

    fn file_of(&self, _: usize) -> PathBuf {
        self.path.clone()
    }

    fn episode_group(&self, e: usize) -> String {
        format!("data/{}", demo(e))
    }

    /// `obs`, and `next_obs` one step earlier: step s is the next observation of step s - 1;
    /// the last step is its own.
    fn frame_targets(&self, ch: &ProfileChannel, e: usize, run: Run) -> Vec<FrameTarget> {
        let Run { lo, n, len } = run;
        let target = |path: String, at, from, to| FrameTarget { path, at, from, to };
        let mut out = vec![target(ch.array_of(e), lo, 0, n)];
        if let Some(next) = next_obs(ch, e) {
            out.push(match lo {
                0 => target(next.clone(), 0, 1, n),
                _ => target(next.clone(), lo - 1, 0, n),
            });
            if lo + n == len {
                out.push(target(next, len - 1, n - 1, n));
            }
        }
        out
    }

    /// Raw float64 values, `next_obs` shifted by one step, `dones` and zero `rewards`.
    fn finish_episode(&self, file: &File, e: usize, len: usize, lowdim: &[Rows]) -> Result<()> {
        let g = file.group(&format!("data/{}", demo(e)))?;
        for (ch, raw) in lowdim {
            let values: Vec<f64> = raw.iter().map(|&v| f64::from(v)).collect();
            let mut dims = vec![len];
            dims.extend(&ch.shape);
            new_dataset(file, &ch.array_of(e), &dims, &values)?;
            if let Some(next) = next_obs(ch, e) {
                let width = values.len() / len.max(1);
                let mut shifted = values[width.min(values.len())..].to_vec();
                shifted.extend_from_slice(&values[values.len() - width..]);
                new_dataset(file, &next, &dims, &shifted)?;
            }
        }
        let mut dones = vec![0u8; len];
        if let Some(last) = dones.last_mut() {
            *last = 1;
        }
        new_dataset(&g, "dones", &[len], &dones)?;
        new_dataset(&g, "rewards", &[len], &vec![0.0f64; len])?;
        Ok(())
    }
}
