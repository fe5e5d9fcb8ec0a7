//! The one writer path of the native HDF5 exports (`act_episodes`, `robomimic`): both store raw
//! values under their codebase's own names, so they share everything but the layout.
//!
//! [`NativeHdf5Writer`] is the [`Sink`]: it keeps the raw low-dim stores until `finish`, writes
//! each run of frames into the datasets the [`NativeLayout`] names (through
//! [`super::hdf5_rows::write_rows`], as chunkc's own HDF5 layouts do), and hands every episode's raw
//! low-dim rows to the layout at the end. A layout says only which file holds an episode, where
//! its frames go, and what it writes per episode. The helpers below create files, groups and
//! datasets with object time tracking off, so the bytes depend only on the contents.

use std::borrow::Cow;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use hdf5::{Dataset, File, Group};

use super::hdf5_rows::write_rows;
use super::source_marks::SourceMarks;
use super::{FrameEncoding, Frames, Sink, SinkContext, WindowIndex};
use crate::error::{Error, Result};
use crate::plan::ProfileChannel;
use crate::source::ChannelKind;
use crate::stats::normalize::RowNormalizer;
use crate::store::LowdimStore;
use crate::window::EpisodeEnds;

/// Where frames of one channel go: `rows` of dataset `path`, from row `at`, are frames
/// `from..to` of the run being written.
pub(super) struct FrameTarget {
    pub path: String,
    pub at: usize,
    pub from: usize,
    pub to: usize,
}

/// A run of frames of one episode: rows `lo..lo + n` of an episode of `len` steps.
#[derive(Debug, Clone, Copy)]
pub(super) struct Run {
    pub lo: usize,
    pub n: usize,
    pub len: usize,
}

/// One low-dim channel of an episode with its raw rows.
pub(super) type Rows<'a> = (&'a ProfileChannel, Cow<'a, [f32]>);

/// What differs between the native HDF5 exports.
pub(super) trait NativeLayout: Send {
    /// The file `meta.json` names as the data.
    fn data_file(&self) -> &str;
    /// The file holding episode `e`.
    fn file_of(&self, e: usize) -> PathBuf;
    /// Where a run of frames (`0..run.n`) of channel `ch` in episode `e` is written.
    fn frame_targets(&self, ch: &ProfileChannel, e: usize, run: Run) -> Vec<FrameTarget>;
    /// Writes episode `e` (of `len` steps) once every value is in.
    fn finish_episode(&self, file: &File, e: usize, len: usize, lowdim: &[Rows]) -> Result<()>;
    /// The group holding episode `e` (a training mixture's `source` attribute goes there).
    fn episode_group(&self, e: usize) -> String;
}

/// A native HDF5 export being written: the shared [`Sink`] of every [`NativeLayout`].
pub struct NativeHdf5Writer<L> {
    pub(super) layout: L,
    /// A training mixture's source of each episode and its own dimensions.
    pub(super) marks: Option<SourceMarks>,
    pub(super) ends: EpisodeEnds,
    pub(super) channels: Vec<ProfileChannel>,
    pub(super) raw: Vec<Option<Arc<LowdimStore>>>,
}

impl<L> NativeHdf5Writer<L> {
    pub(super) fn new(layout: L, ctx: &SinkContext, channels: Vec<ProfileChannel>) -> Self {
        let ends = ctx.episode_ends;
        NativeHdf5Writer {
            layout,
            marks: SourceMarks::of(ctx),
            ends: EpisodeEnds::from(ends),
            raw: channels.iter().map(|_| None).collect(),
            channels,
        }
    }
}

/// Creates an HDF5 file whose bytes depend only on what is written into it.
pub(super) fn create_file(path: &Path) -> Result<File> {
    File::with_options()
        .with_fcpl(|p| p.obj_track_times(false))
        .create(path)
        .map_err(|e| Error::output(format!("cannot create {}: {e}", path.display())))
}

pub(super) fn open_rw(path: &Path) -> Result<File> {
    File::open_rw(path).map_err(|e| Error::output(format!("cannot open {}: {e}", path.display())))
}

pub(super) fn group(parent: &Group, name: &str) -> Result<Group> {
    Ok(parent
        .create_group_builder()
        .obj_track_times(false)
        .create(name)?)
}

/// An empty `(len, shape...)` frame dataset, one frame per chunk, uncompressed (as ACT's and
/// robomimic's own image datasets are).
pub(super) fn frames_dataset(file: &File, path: &str, len: usize, shape: &[usize]) -> Result<()> {
    let mut full = vec![len];
    full.extend(shape);
    let mut chunk = vec![1];
    chunk.extend(shape);
    file.new_dataset::<u8>()
        .shape(full)
        .chunk(chunk)
        .obj_track_times(false)
        .create(path)?;
    Ok(())
}

/// A new contiguous dataset `path` of `dims` holding `values`.
pub(super) fn new_dataset<T: hdf5::H5Type>(
    loc: &Group,
    path: &str,
    dims: &[usize],
    values: &[T],
) -> Result<Dataset> {
    let ds = loc
        .new_dataset::<T>()
        .shape(dims)
        .obj_track_times(false)
        .create(path)?;
    ds.write_raw(values)?;
    Ok(ds)
}

impl<L: NativeLayout> Sink for NativeHdf5Writer<L> {
    fn data_file(&self) -> &str {
        self.layout.data_file()
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
        let e = self.ends.partition_point(|&end| end as usize <= row);
        let (start, end) = (self.ends.start(e), self.ends.range(e).end);
        let file = open_rw(&self.layout.file_of(e))?;
        let ch = &self.channels[channel];
        let run = Run {
            lo: row - start,
            n: frames.len(),
            len: end - start,
        };
        for t in self.layout.frame_targets(ch, e, run) {
            if t.from < t.to {
                write_rows(&file.dataset(&t.path)?, t.at, frames.span(t.from, t.to))?;
            }
        }
        file.close()?;
        Ok(())
    }

    /// Raw values: the codebase normalizes in its own code (ACT with `dataset_stats.pkl`).
    fn write_lowdim(
        &mut self,
        channel: usize,
        raw: &Arc<LowdimStore>,
        _: &RowNormalizer,
    ) -> Result<()> {
        self.raw[channel] = Some(Arc::clone(raw));
        Ok(())
    }

    fn write_index(&mut self, _: &dyn WindowIndex) -> Result<()> {
        Ok(())
    }

    /// Episode by episode, in stored order; a file is opened once for the episodes it holds.
    fn finish(self: Box<Self>) -> Result<super::Finished> {
        let mut open: Option<(PathBuf, File)> = None;
        for e in 0..self.ends.len() {
            let (lo, hi) = (self.ends.start(e), self.ends.range(e).end);
            let path = self.layout.file_of(e);
            if open.as_ref().is_none_or(|(p, _)| *p != path) {
                if let Some((_, file)) = open.take() {
                    file.close()?;
                }
                open = Some((path.clone(), open_rw(&path)?));
            }
            let (_, file) = open.as_ref().expect("opened above");
            let mut lowdim = Vec::new();
            for (ch, raw) in self.channels.iter().zip(&self.raw) {
                if let (ChannelKind::Lowdim, Some(raw)) = (ch.kind, raw) {
                    lowdim.push((ch, raw.rows(lo, hi)?));
                }
            }
            self.layout.finish_episode(file, e, hi - lo, &lowdim)?;
            if let Some(marks) = &self.marks {
                let group = self.layout.episode_group(e);
                let channel_of = |ch: &ProfileChannel| {
                    let found = self.channels.iter().position(|c| c.name == ch.name);
                    found.expect("a profile channel")
                };
                let channels: Vec<&ProfileChannel> = lowdim.iter().map(|(ch, _)| *ch).collect();
                marks.write(file, &group, e, &channels, |ch| ch.array_of(e), channel_of)?;
            }
        }
        if let Some((_, file)) = open {
            file.close()?;
        }
        Ok(super::Finished::default())
    }
}
