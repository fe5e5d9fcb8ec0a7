//! A training mixture's sources as its joined manifest keeps them ([`SourcePart`]), and what the
//! manifest says of each episode's source: which one, its own width of a channel, where it is
//! for messages. A single source is one source of every channel's width.

use serde::Serialize;

use super::{Manifest, SourceSplit};
use crate::spec::SourceFormat;

/// One source of a training mixture, as the joined manifest keeps it.
#[derive(Debug, Clone, Serialize)]
pub struct SourcePart {
    /// `[sources.<name>]`'s name.
    pub name: String,
    pub format: SourceFormat,
    /// As written in the spec.
    pub path: String,
    /// Its own recording rate (its episodes are converted to the mixture's `fps` when read).
    pub fps: f64,
    pub weight: f64,
    pub fingerprint: String,
    /// Mixture id of its episode 0: mixture id = `id_offset` + its own id.
    pub id_offset: u64,
    /// Per mixture channel (manifest order): its own width, 0 where it lacks the channel (the
    /// rest of a padded channel is zeros).
    pub widths: Vec<usize>,
    /// The split the source stores, in its own ids (`[split] from = "source"`).
    #[serde(skip)]
    pub source_split: Option<SourceSplit>,
}

impl SourcePart {
    /// The index, among `parts` (a mixture's, in order), of the source mixture episode `id`
    /// belongs to (0 when there are none).
    pub fn index_of(parts: &[SourcePart], id: u64) -> usize {
        parts.iter().rposition(|p| p.id_offset <= id).unwrap_or(0)
    }
}

impl Manifest {
    /// The values per row episode `id` holds of channel `c` (a low-dim channel): a training
    /// mixture source's own width (the rest of a row is padding; 0 where it lacks the channel),
    /// else the channel's.
    pub fn own_width(&self, c: usize, id: u64) -> usize {
        let part = self.parts.get(self.source_of(id));
        part.map_or(self.channels[c].width(), |p| p.widths[c])
    }

    /// Channel `c`'s values per row in each source: a training mixture's sources' own widths (0
    /// where one lacks it), else the channel's width, for the one source.
    pub fn source_widths(&self, c: usize) -> Vec<usize> {
        match self.parts.is_empty() {
            true => vec![self.channels[c].width()],
            false => self.parts.iter().map(|p| p.widths[c]).collect(),
        }
    }

    /// The index of the mixture source episode `id` belongs to (0 for one source).
    pub fn source_of(&self, id: u64) -> usize {
        SourcePart::index_of(&self.parts, id)
    }

    /// Where episode `id` comes from, for messages: `path: episode 3`, or in a mixture
    /// `sources.sim (path): episode 3` with the source's own id.
    pub fn place(&self, id: u64, path: &str) -> String {
        match self.parts.get(self.source_of(id)) {
            Some(p) => format!(
                "sources.{} ({}): episode {}",
                p.name,
                p.path,
                id - p.id_offset
            ),
            None => format!("{path}: episode {id}"),
        }
    }
}
