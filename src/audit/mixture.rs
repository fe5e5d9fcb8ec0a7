//! A training mixture (`[sources.<name>]`) as one [`Source`]: the sources, each opened and audited
//! on its own, joined so that everything downstream reads one manifest.
//!
//! - Episode ids are made unique: a source's id plus its `id_offset` (the sum of the id spans of
//!   the sources before it, taken before the audit, so that verdicts never move them). Episodes
//!   are stored source by source, in name order.
//! - Every source is converted, as it is read, to the mixture's rate (the fastest profile's):
//!   integer ratios keep one step in k, others resample (`[audit] resample`).
//! - An episode without a task of its own gets its source's name as its task.
//! - Channels are the union of the sources'. A low-dim channel named in `[mixture] pad_to` is
//!   zero-filled to that width (all zeros where a source lacks it); any other channel must be
//!   the same in every source. The build reads each episode unpadded, at its source's own width
//!   ([`Source::read_unpadded`]), and pads only what it writes; `read_episode` pads.

use std::collections::BTreeMap;
use std::sync::Arc;

use super::conversion::{conversion, Conversion};
use super::sources_doctor::SourcesDoctor;

use crate::error::Result;
use crate::source::fingerprint::Fingerprint;
use crate::source::{
    ChannelData, ChannelInfo, DecodeCounts, Episode, EpisodeInfo, Manifest, Source, SourcePart,
    SourceSplit, VideoCheck,
};
use crate::spec::{LoadedSpec, SourceView};

/// One audited source of a mixture, ready to be joined.
pub struct Part {
    pub view: SourceView,
    pub source: Box<dyn Source>,
    /// Its first mixture id (see the module docs).
    pub id_offset: u64,
    /// The split the source stores, in its own ids (the opened manifest's).
    pub source_split: Option<SourceSplit>,
}

pub struct Mixture {
    parts: Vec<Box<dyn Source>>,
    manifest: Manifest,
    /// Per mixture position: the part and the position in it.
    positions: Vec<(usize, usize)>,
    /// Per part: from its rate to the mixture's.
    conversions: Vec<Conversion>,
    /// Per part, per mixture channel: the part's channel position, if it maps the channel.
    channel_of: Vec<Vec<Option<usize>>>,
    /// The sources' dataset doctor, fed every episode as read (at its source's rate).
    doctor: Option<Arc<SourcesDoctor>>,
}

/// Each part's name and channels.
fn listed(parts: &[Part]) -> Vec<(&str, &[ChannelInfo])> {
    parts
        .iter()
        .map(|p| {
            (
                p.view.name.as_str(),
                p.source.manifest().channels.as_slice(),
            )
        })
        .collect()
}

/// The id offsets of sources whose opened manifests are `manifests`, in order.
pub fn id_offsets<'a>(manifests: impl Iterator<Item = &'a Manifest>) -> Vec<u64> {
    let mut next = 0u64;
    manifests
        .map(|m| {
            let offset = next;
            next += m.episodes.iter().map(|e| e.id + 1).max().unwrap_or(0);
            offset
        })
        .collect()
}

impl Mixture {
    /// Joins `parts` (in name order) at `fps`.
    pub fn new(spec: &LoadedSpec, parts: Vec<Part>, fps: f64) -> Result<Mixture> {
        let channels = super::channel_union::joined(spec, &listed(&parts))?;
        let conversions = conversions(spec, &parts, fps)?;
        let mut manifest = Manifest {
            format: parts[0].source.manifest().format,
            fps,
            episodes: Vec::new(),
            channels: channels.clone(),
            fingerprint: Fingerprint::default().into(),
            timestamps: false,
            source_split: None,
            warnings: Vec::new(),
            tasks: BTreeMap::new(),
            parts: Vec::new(),
        };
        let mut positions = Vec::new();
        let mut fingerprint = blake3::Hasher::new();
        let mut files = BTreeMap::new();
        let mut channel_of = Vec::new();
        for (s, part) in parts.iter().enumerate() {
            let own = part.source.manifest();
            let name = &part.view.name;
            // A mixture's sources are each hashed at open (their files cover the mixture's).
            let print = own.fingerprint.get()?;
            for (i, e) in own.episodes.iter().enumerate() {
                manifest.episodes.push(EpisodeInfo {
                    id: part.id_offset + e.id,
                    len: conversions[s].len(e.len),
                });
                positions.push((s, i));
            }
            for (path, hash) in &print.files {
                files.insert(format!("{name}/{path}"), hash.clone());
            }
            // An episode without a task of its own has its source's name as its task (the
            // LeRobot export's `task` then tells the sources apart).
            for e in &own.episodes {
                let task = own.tasks.get(&e.id).unwrap_or(name);
                manifest.tasks.insert(part.id_offset + e.id, task.clone());
            }
            let warnings = own.warnings.iter().map(|w| format!("sources.{name}: {w}"));
            manifest.warnings.extend(warnings);
            for text in [name, &print.hash] {
                fingerprint.update(&(text.len() as u64).to_le_bytes());
                fingerprint.update(text.as_bytes());
            }
            let map: Vec<Option<usize>> = channels
                .iter()
                .map(|c| own.channels.iter().position(|o| o.name == c.name))
                .collect();
            manifest.parts.push(SourcePart {
                name: name.clone(),
                format: own.format,
                path: part.view.spec.source().path.clone(),
                fps: own.fps,
                weight: part.view.weight,
                fingerprint: print.hash.clone(),
                id_offset: part.id_offset,
                widths: map
                    .iter()
                    .map(|k| k.map_or(0, |k| own.channels[k].width()))
                    .collect(),
                source_split: part.source_split.clone(),
            });
            channel_of.push(map);
        }
        manifest.fingerprint = Fingerprint {
            hash: fingerprint.finalize().to_hex().to_string(),
            files,
        }
        .into();
        Ok(Mixture {
            parts: parts.into_iter().map(|p| p.source).collect(),
            manifest,
            positions,
            conversions,
            channel_of,
            doctor: None,
        })
    }

    /// Feeds `doctor` every episode as it is read, at its source's own rate and width.
    pub fn ride(&mut self, doctor: Arc<SourcesDoctor>) {
        self.doctor = Some(doctor);
    }

    /// Per part: whether the mixture's rate keeps its steps (its values are read as they are).
    pub fn keeps_steps(&self) -> Vec<bool> {
        let same = Conversion::Decimate { factor: 1 };
        self.conversions.iter().map(|&c| c == same).collect()
    }

    /// `positions` (sorted) per part, translated to the part's own positions.
    fn by_part(&self, positions: &[usize]) -> Vec<Vec<usize>> {
        let mut out = vec![Vec::new(); self.parts.len()];
        for &i in positions {
            let (s, j) = self.positions[i];
            out[s].push(j);
        }
        out
    }
}

/// Each part's conversion to the mixture's rate `fps`; a source slower than it is refused.
fn conversions(spec: &LoadedSpec, parts: &[Part], fps: f64) -> Result<Vec<Conversion>> {
    let mut conversions = Vec::new();
    for part in parts {
        let own = part.source.manifest().fps;
        let c = conversion(own, fps, spec.spec.audit.resample).map_err(|_| {
            spec.error_at(
                &["sources", &part.view.name],
                format!(
                    "source `{}` runs at {own} Hz, slower than the mixture's {fps} Hz (its fastest profile's rate); chunkc does not upsample",
                    part.view.name
                ),
                Some(format!("set every profile's `fps` to {own} or less, or leave the source out")),
            )
        })?;
        conversions.push(c);
    }
    Ok(conversions)
}

impl Source for Mixture {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        let mut episode = self.read_unpadded(index)?;
        let (s, _) = self.positions[index];
        let part = &self.manifest.parts[s];
        for (c, ch) in self.manifest.channels.iter().enumerate() {
            let values =
                std::mem::replace(&mut episode.channels[c], ChannelData::Lowdim(Vec::new()));
            episode.channels[c] = pad(values, episode.len, part.widths[c], ch.width());
        }
        Ok(episode)
    }

    /// The episode as its source reads it, converted to the mixture's rate: its low-dim
    /// channels at its own width (nothing where it lacks one), not padded.
    fn read_unpadded(&self, index: usize) -> Result<Episode> {
        let (s, j) = self.positions[index];
        let mut own = self.parts[s].read_episode(j)?;
        if let Some(doctor) = &self.doctor {
            doctor.take(index, s, &own);
        }
        let conv = self.conversions[s];
        let same = conv == Conversion::Decimate { factor: 1 };
        let part = &self.manifest.parts[s];
        let len = conv.len(own.len);
        let source_channels = &self.parts[s].manifest().channels;
        let mut channels = Vec::with_capacity(self.manifest.channels.len());
        let mut packets = BTreeMap::new();
        for c in 0..self.manifest.channels.len() {
            let Some(k) = self.channel_of[s][c] else {
                channels.push(ChannelData::Lowdim(Vec::new()));
                continue;
            };
            let values = std::mem::replace(&mut own.channels[k], ChannelData::Lowdim(Vec::new()));
            let values = match same {
                true => values,
                false => conv.apply(&values, source_channels[k].width(), own.len),
            };
            if same {
                if let Some(p) = own.packets.remove(&k) {
                    packets.insert(c, p);
                }
            }
            channels.push(values);
        }
        Ok(Episode {
            id: part.id_offset + own.id,
            len,
            timestamps: None,
            channels,
            packets,
        })
    }

    fn read_timestamps(&self, _index: usize) -> Result<Option<Vec<f64>>> {
        Ok(None)
    }

    fn decode_counts(&self) -> DecodeCounts {
        let mut out = DecodeCounts::new();
        for (part, source) in self.manifest.parts.iter().zip(&self.parts) {
            for (array, counts) in source.decode_counts() {
                out.insert(format!("{}/{array}", part.name), counts);
            }
        }
        out
    }

    fn prefetch(&self, positions: &[usize]) {
        for (source, own) in self.parts.iter().zip(self.by_part(positions)) {
            if !own.is_empty() {
                source.prefetch(&own);
            }
        }
    }

    fn video_checks(&self, index: usize) -> Result<Vec<VideoCheck>> {
        // Each source's videos were checked by its own audit.
        let _ = index;
        Ok(Vec::new())
    }

    fn only_reading(&mut self, positions: &[usize]) {
        let by_part = self.by_part(positions);
        for (source, own) in self.parts.iter_mut().zip(by_part) {
            source.only_reading(&own);
        }
    }
}

/// `rows` rows of `own` values zero-filled to `width` values each.
fn pad(values: ChannelData, rows: usize, own: usize, width: usize) -> ChannelData {
    match values {
        ChannelData::Lowdim(v) if own < width => {
            let mut out = Vec::with_capacity(rows * width);
            for row in v.chunks_exact(own.max(1)).take(rows) {
                out.extend_from_slice(row);
                out.resize(out.len() + width - own, 0.0);
            }
            out.resize(rows * width, 0.0);
            ChannelData::Lowdim(out)
        }
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pads_rows_with_zeros() {
        let ChannelData::Lowdim(v) = pad(ChannelData::Lowdim(vec![1.0, 2.0, 3.0, 4.0]), 2, 2, 3)
        else {
            panic!()
        };
        assert_eq!(v, vec![1.0, 2.0, 0.0, 3.0, 4.0, 0.0]);
        // A source without the channel: zeros.
        let ChannelData::Lowdim(v) = pad(ChannelData::Lowdim(Vec::new()), 2, 0, 2) else {
            panic!()
        };
        assert_eq!(v, vec![0.0; 4]);
    }
}
