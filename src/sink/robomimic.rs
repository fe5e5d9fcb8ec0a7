//! robomimic's dataset layout (`format = "robomimic_hdf5"`): one `data.hdf5` that robomimic's
//! `SequenceDataset` opens directly.
//!
//! ```text
//! data.hdf5
//!   /data  @total = sum of T, @env_args = '{"env_name": "", "type": 1, "env_kwargs": {}}'
//!   /data/demo_<i>          i = 0..E-1 in stored order, @num_samples = T
//!     actions               (T, A) float64 raw (the `action` channel)
//!     obs/<name>            (T, D) float64 raw, or (T, H, W, C) uint8 frames; <name> is the
//!                           channel name without `observation.`
//!     dones                 (T,) uint8, 1 at the last step
//!     rewards               (T,) float64 zeros
//!   /mask/train, /mask/valid  byte strings: the demo names of each split
//! ```
//! Values are raw: robomimic normalizes in its own code. chunkc's loader does not read this
//! format (there is no window index in it).

use std::path::{Path, PathBuf};
use std::sync::Arc;

use hdf5::types::{FixedAscii, VarLenUnicode};
use hdf5::{File, Group};

use super::{FrameEncoding, Frames, Sink, SinkContext, WindowIndex};
use crate::error::{Error, Result};
use crate::exec::LowdimStore;
use crate::source::ChannelKind;
use crate::stats::normalize::Normalizer;

pub const ROBOMIMIC_FILE: &str = "data.hdf5";
const ENV_ARGS: &str = r#"{"env_name": "", "type": 1, "env_kwargs": {}}"#;

pub struct RobomimicWriter {
    path: PathBuf,
    ends: Vec<u64>,
    /// Per channel: the name, its shape, its kind.
    channels: Vec<(String, Vec<usize>, ChannelKind)>,
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

/// `observation.image` → `image`.
fn obs_name(name: &str) -> &str {
    name.strip_prefix("observation.").unwrap_or(name)
}

fn demo(e: usize) -> String {
    format!("demo_{e}")
}

impl RobomimicWriter {
    pub fn create(ctx: &SinkContext) -> Result<Self> {
        let channels: Vec<(String, Vec<usize>, ChannelKind)> = ctx
            .profile
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.shape.clone(), c.kind))
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
            let obs = group(&g, "obs")?;
            for (name, shape, kind) in &channels {
                if *kind != ChannelKind::Image {
                    continue;
                }
                let mut full = vec![len];
                full.extend(shape);
                let mut chunk = vec![1];
                chunk.extend(shape);
                obs.new_dataset::<u8>()
                    .shape(full)
                    .chunk(chunk)
                    .obj_track_times(false)
                    .create(obs_name(name))?;
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
            ends: ctx.episode_ends.to_vec(),
            raw: channels.iter().map(|_| None).collect(),
            channels,
        })
    }

    fn episode_of(&self, row: usize) -> (usize, usize) {
        let e = self.ends.partition_point(|&end| end as usize <= row);
        let start = if e == 0 { 0 } else { self.ends[e - 1] as usize };
        (e, start)
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
        let file = open_rw(&self.path)?;
        let (name, shape, _) = &self.channels[channel];
        let ds = file.dataset(&format!("data/{}/obs/{}", demo(e), obs_name(name)))?;
        let mut dims = vec![frames.len()];
        dims.extend(shape);
        let view = ndarray::ArrayViewD::from_shape(ndarray::IxDyn(&dims), frames.bytes())
            .map_err(|err| Error::Internal(format!("frames of {name}: {err}")))?;
        let mut sel: Vec<hdf5::SliceOrIndex> =
            vec![(row - start..row - start + frames.len()).into()];
        sel.extend(shape.iter().map(|&d| hdf5::SliceOrIndex::from(0..d)));
        ds.write_slice(view, hdf5::Hyperslab::from(sel))?;
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
            for ((name, shape, kind), raw) in self.channels.iter().zip(&self.raw) {
                let (ChannelKind::Lowdim, Some(raw)) = (kind, raw) else {
                    continue;
                };
                let values: Vec<f64> = raw.rows(lo, hi)?.iter().map(|&v| f64::from(v)).collect();
                let mut dims = vec![hi - lo];
                dims.extend(shape);
                let path = if name == "action" {
                    "actions".to_string()
                } else {
                    format!("obs/{}", obs_name(name))
                };
                g.new_dataset::<f64>()
                    .shape(dims)
                    .obj_track_times(false)
                    .create(path.as_str())?
                    .write_raw(&values)?;
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
