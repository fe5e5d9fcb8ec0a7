//! ACT's own layout (`format = "act_episodes"`): one `episode_<i>.hdf5` per stored episode,
//! `i` = 0..E-1 in stored order (ACT's `load_data` needs contiguous ids from 0).
//!
//! ```text
//! episode_<i>.hdf5
//!   @sim = True                      actions start at the observation's step (chunkc's
//!                                    `current` alignment)
//!   /action                (T, A) float32 raw
//!   /observations/qpos     (T, D) float32 raw (the state channel; see `codebase::state_channel`)
//!   /observations/qvel     (T, D) float32 zeros (ACT reads it but never uses it)
//!   /observations/<name>   (T, D) float32 raw, every other low-dim observation
//!   /observations/images/<cam>  (T, H, W, C) uint8, one frame per chunk, uncompressed
//! ```
//! Values are raw: ACT normalizes with `dataset_stats.pkl`, written beside the episodes (the
//! `act` statistics format is always on for this format).

use std::path::PathBuf;
use std::sync::Arc;

use hdf5::{File, Group};

use super::{FrameEncoding, Frames, Sink, SinkContext, WindowIndex};
use crate::error::{Error, Result};
use crate::exec::LowdimStore;
use crate::render::codebase::state_channel;
use crate::source::ChannelKind;
use crate::stats::normalize::Normalizer;

pub struct ActEpisodesWriter {
    dir: PathBuf,
    ends: Vec<u64>,
    /// Per channel: the name, its shape, its kind.
    channels: Vec<(String, Vec<usize>, ChannelKind)>,
    state: Option<String>,
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
        let channels: Vec<(String, Vec<usize>, ChannelKind)> = ctx
            .profile
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.shape.clone(), c.kind))
            .collect();
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
            let images = group(&obs, "images")?;
            for (name, shape, kind) in &channels {
                if *kind != ChannelKind::Image {
                    continue;
                }
                let mut full = vec![len];
                full.extend(shape);
                let mut chunk = vec![1];
                chunk.extend(shape);
                images
                    .new_dataset::<u8>()
                    .shape(full)
                    .chunk(chunk)
                    .obj_track_times(false)
                    .create(camera(name))?;
            }
            file.close()?;
        }
        Ok(ActEpisodesWriter {
            dir: ctx.dir.to_path_buf(),
            ends: ctx.episode_ends.to_vec(),
            state: state_channel(ctx.profile).map(|c| c.name.clone()),
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

/// `observation.image` → `image`: ACT names cameras by their key under `images/`.
fn camera(name: &str) -> &str {
    name.strip_prefix("observation.").unwrap_or(name)
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
        let (name, shape, _) = &self.channels[channel];
        let ds = file.dataset(&format!("observations/images/{}", camera(name)))?;
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
        let mut start = 0usize;
        for (e, &end) in self.ends.iter().enumerate() {
            let (lo, hi) = (start, end as usize);
            start = hi;
            let file = open_rw(&episode_file(&self.dir, e))?;
            for ((name, shape, kind), raw) in self.channels.iter().zip(&self.raw) {
                let (ChannelKind::Lowdim, Some(raw)) = (kind, raw) else {
                    continue;
                };
                let values = raw.rows(lo, hi)?;
                let mut dims = vec![hi - lo];
                dims.extend(shape);
                let path = if name == "action" {
                    "action".to_string()
                } else if Some(name) == self.state.as_ref() {
                    "observations/qpos".to_string()
                } else {
                    format!("observations/{}", camera(name))
                };
                let write = |path: &str, values: &[f32]| -> Result<()> {
                    file.new_dataset::<f32>()
                        .shape(dims.clone())
                        .obj_track_times(false)
                        .create(path)?
                        .write_raw(values)?;
                    Ok(())
                };
                write(&path, &values)?;
                if path == "observations/qpos" {
                    write("observations/qvel", &vec![0.0; values.len()])?;
                }
            }
            file.close()?;
        }
        Ok(())
    }
}
