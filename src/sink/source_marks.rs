//! A training mixture's marks in the native HDF5 exports (ACT episodes, robomimic demos): each
//! episode names the source it comes from (a `source` attribute), and each of its low-dim arrays
//! says which dimensions are that source's own (a `dim_mask` attribute, true on them; the rest
//! is the zero padding of `[mixture] pad_to`). ACT's and robomimic's loaders read only the arrays
//! their configurations name, so the marks ride along without changing what they train on.

use hdf5::types::VarLenUnicode;
use hdf5::File;

use super::SinkContext;
use crate::error::{Error, Result};
use crate::plan::ProfileChannel;

/// Per stored episode, its source's name and the own width of each profile channel.
pub(super) struct SourceMarks {
    names: Vec<String>,
    /// Per source, per profile channel (manifest order).
    widths: Vec<Vec<usize>>,
    episode_sources: Vec<usize>,
}

impl SourceMarks {
    /// `None` for one source.
    pub fn of(ctx: &SinkContext) -> Option<SourceMarks> {
        if ctx.source_parts.is_empty() {
            return None;
        }
        Some(SourceMarks {
            names: ctx.source_parts.iter().map(|p| p.name.clone()).collect(),
            widths: ctx.source_parts.iter().map(|p| p.widths.clone()).collect(),
            episode_sources: ctx.episode_sources.to_vec(),
        })
    }

    /// Marks episode `e`: `source` on the group `group` of `file`, `dim_mask` on each low-dim
    /// array (`array(ch)`, its path in the file).
    pub fn write(
        &self,
        file: &File,
        group: &str,
        e: usize,
        lowdim: &[&ProfileChannel],
        array: impl Fn(&ProfileChannel) -> String,
        channel_of: impl Fn(&ProfileChannel) -> usize,
    ) -> Result<()> {
        let s = self.episode_sources[e];
        let name = self.names[s]
            .parse::<VarLenUnicode>()
            .map_err(|err| Error::Internal(format!("source name: {err}")))?;
        file.group(group)?
            .new_attr::<VarLenUnicode>()
            .create("source")?
            .write_scalar(&name)?;
        for ch in lowdim {
            let width: usize = ch.shape.iter().product();
            let own = self.widths[s][channel_of(ch)];
            let mask: Vec<bool> = (0..width).map(|d| d < own).collect();
            file.dataset(&array(ch))?
                .new_attr::<bool>()
                .shape([width])
                .create("dim_mask")?
                .write(&mask)?;
        }
        Ok(())
    }
}
