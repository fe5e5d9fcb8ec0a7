//! ACT / ALOHA's layout: `episodes/episode_<i>.hdf5`, one file per episode, as ACT's
//! `record_episodes.py` writes them (uncompressed frames, one chunk per frame).
//!
//! ```text
//! /action                      (T, A) float32
//! /observations/qpos           (T, S) float32
//! /observations/qvel           (T, S) float32
//! /observations/images/cam<c>  (T, H, W, 3) uint8, chunks (1, H, W, 3)
//! attrs: sim = true, compress = false
//! ```
//! ALOHA stores no timestamps, so only a `drop` fault leaves a trace (shorter episodes).

use std::path::{Path, PathBuf};

use hdf5::File;

use super::{SynthEpisode, SynthOptions, SynthWriter};
use crate::error::{Error, IoContext, Result};

pub struct AlohaWriter {
    dir: PathBuf,
    opts: SynthOptions,
}

impl AlohaWriter {
    pub fn create(opts: &SynthOptions, dir: &Path) -> Result<Self> {
        std::fs::create_dir_all(dir).at("create", dir)?;
        Ok(AlohaWriter {
            dir: dir.to_path_buf(),
            opts: opts.clone(),
        })
    }
}

/// Creates a file whose bytes depend only on what is written into it.
pub fn create_file(path: &Path) -> Result<File> {
    File::with_options()
        .with_fcpl(|p| p.obj_track_times(false))
        .create(path)
        .map_err(|e| Error::output(format!("cannot create {}: {e}", path.display())))
}

/// Writes `(rows, shape...)` values as a contiguous dataset.
pub fn dataset<T: hdf5::H5Type>(
    group: &hdf5::Group,
    name: &str,
    values: &[T],
    shape: &[usize],
) -> Result<()> {
    let ds = group
        .new_dataset::<T>()
        .shape(shape)
        .obj_track_times(false)
        .create(name)?;
    ds.write_raw(values)?;
    Ok(())
}

/// Writes frames `(T, H, W, 3)` with one chunk per frame, uncompressed (as ALOHA does).
pub fn frames(
    group: &hdf5::Group,
    name: &str,
    values: &[u8],
    steps: usize,
    h: usize,
    w: usize,
) -> Result<()> {
    let ds = group
        .new_dataset::<u8>()
        .shape([steps, h, w, 3])
        .chunk([1, h, w, 3])
        .obj_track_times(false)
        .create(name)?;
    ds.write_raw(values)?;
    Ok(())
}

pub fn group(parent: &hdf5::Group, name: &str) -> Result<hdf5::Group> {
    Ok(parent
        .create_group_builder()
        .obj_track_times(false)
        .create(name)?)
}

impl SynthWriter for AlohaWriter {
    fn episode(&mut self, ep: &SynthEpisode) -> Result<()> {
        let o = &self.opts;
        let path = self.dir.join(format!("episode_{}.hdf5", ep.id));
        let f = create_file(&path)?;
        f.new_attr::<bool>().create("sim")?.write_scalar(&true)?;
        f.new_attr::<bool>()
            .create("compress")?
            .write_scalar(&false)?;
        dataset(&f, "action", &ep.action, &[ep.steps, o.action_dim])?;
        let obs = group(&f, "observations")?;
        dataset(&obs, "qpos", &ep.state, &[ep.steps, o.state_dim])?;
        dataset(&obs, "qvel", &ep.velocity, &[ep.steps, o.state_dim])?;
        if o.cameras > 0 {
            let images = group(&obs, "images")?;
            for (c, fr) in ep.frames.iter().enumerate() {
                frames(&images, &format!("cam{c}"), fr, ep.steps, o.height, o.width)?;
            }
        }
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<()> {
        Ok(())
    }
}
