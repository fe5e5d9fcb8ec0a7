//! Which parts of chunkc's loader a profile's `loader.py` holds, decided once, from the plan.
//!
//! `templates/loader.py.j2` puts the loader together from the parts in `templates/loader/`: the
//! core (windows and normalization) and the workers in every profile's file, the rest only where
//! the profile reads them, so that the file a user opens holds the code of their dataset and no
//! other. The parts follow what `meta.json` describes (its `data_format`, each camera's
//! `storage`, `transforms`, `sources`, `sampling`, `stats_population`), and the loader refuses a
//! `meta.json` that needs a part it lacks ([`Parts::lacking`]).

use serde::Serialize;

use crate::plan::{Plan, ProfilePlan};
use crate::source::ChannelKind;
use crate::spec::{ImageCompression, OutputFormat, StatsPopulation};
use crate::transform::Op;
use crate::window::Sampling;

/// The optional parts of the loader, each a template in `templates/loader/` (or a few lines of
/// one) that a profile's `loader.py` holds only when it reads that part.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Parts {
    /// The backend of each storage format: `data_format` `hdf5`, `zarr`, `parquet` (LeRobot
    /// v3.0). A native export (`act_episodes`, `robomimic_hdf5`, LeRobot v2.1) has none: it holds
    /// no window index, and its loader refuses it.
    pub hdf5: bool,
    pub zarr: bool,
    pub parquet: bool,
    /// Cameras, whatever their storage: `validate.py`'s renders of the frames (the loader reads a
    /// Zarr camera as any array; the storages below hold their own code).
    pub cameras: bool,
    /// HDF5 cameras stored as pixels (`image_compression` `none` or `gzip`): read with one pread
    /// per frame, inflated with zlib where deflated.
    pub frames: bool,
    /// HDF5 cameras stored as JPEG, and as video.
    pub jpeg: bool,
    pub video: bool,
    /// Parquet cameras stored as PNG, and as mp4 (`image_encoding`).
    pub png: bool,
    pub mp4: bool,
    /// Action transforms, and the rotation math of `rotation` and `relative_pose` (`delta`
    /// needs none).
    pub transforms: bool,
    pub rotations: bool,
    /// A training mixture: each window's source, per-source normalization, the sampler.
    pub mixture: bool,
    /// Hierarchical samples (coarse and fine chunks).
    pub hierarchy: bool,
    /// Segment samples (their window rules are the core's; only the documentation differs).
    pub segments: bool,
    /// Statistics over whole windows (`stats_population = "windows"`), as `validate.py` checks
    /// them.
    pub window_stats: bool,
}

impl Parts {
    /// The parts `p` reads, from what its `meta.json` will say (`plan` tells a mixture).
    pub fn of(plan: &Plan, p: &ProfilePlan) -> Self {
        let v = &p.values;
        let cameras = p.channels.iter().any(|c| c.kind == ChannelKind::Image);
        let hdf5 = v.format == OutputFormat::Hdf5;
        let parquet = v.format == OutputFormat::Parquet && !p.writes_lerobot_v21();
        let hdf5_cameras = hdf5 && cameras;
        let parquet_video = v.video().is_some();
        Parts {
            hdf5,
            zarr: v.format == OutputFormat::Zarr,
            parquet,
            cameras,
            frames: hdf5_cameras
                && matches!(
                    v.image_compression,
                    ImageCompression::None | ImageCompression::Gzip
                ),
            jpeg: hdf5_cameras && v.image_compression == ImageCompression::Jpeg,
            video: hdf5_cameras && v.image_compression == ImageCompression::Video,
            png: parquet && cameras && !parquet_video,
            mp4: parquet && cameras && parquet_video,
            transforms: !p.transforms.is_empty(),
            rotations: p
                .transforms
                .iter()
                .any(|t| !matches!(t.op, Op::Delta { .. })),
            mixture: !plan.source.parts.is_empty(),
            hierarchy: matches!(p.sampling, Sampling::Hierarchy { .. }),
            segments: matches!(p.sampling, Sampling::Segment { .. }),
            window_stats: v.stats_population == StatsPopulation::Windows,
        }
    }

    /// Every part: one loader that reads any profile of this chunkc version.
    pub fn every() -> Self {
        Parts {
            hdf5: true,
            zarr: true,
            parquet: true,
            cameras: true,
            frames: true,
            jpeg: true,
            video: true,
            png: true,
            mp4: true,
            transforms: true,
            rotations: true,
            mixture: true,
            hierarchy: true,
            segments: true,
            window_stats: true,
        }
    }

    /// Each part by name, and whether the loader holds it, in file order.
    fn named(&self) -> [(&'static str, bool); 15] {
        [
            ("hdf5", self.hdf5),
            ("zarr", self.zarr),
            ("parquet", self.parquet),
            ("cameras", self.cameras),
            ("frames", self.frames),
            ("png", self.png),
            ("mp4", self.mp4),
            ("jpeg", self.jpeg),
            ("video", self.video),
            ("transforms", self.transforms),
            ("rotations", self.rotations),
            ("mixture", self.mixture),
            ("hierarchy", self.hierarchy),
            ("segments", self.segments),
            ("window_stats", self.window_stats),
        ]
    }

    /// The parts the loader lacks that a `meta.json` could need, so that it refuses one that
    /// does (instead of reading it wrong): the other storage formats, the other HDF5 camera
    /// storages, transforms (or their rotations), a mixture, hierarchical samples. None for a
    /// native export's loader, which refuses every `meta.json`.
    pub fn lacking(&self) -> Vec<&'static str> {
        if !(self.hdf5 || self.zarr || self.parquet) {
            return vec![];
        }
        let mut out = Vec::new();
        for (name, held) in [
            ("hdf5", self.hdf5),
            ("zarr", self.zarr),
            ("parquet", self.parquet),
        ] {
            if !held {
                out.push(name);
            }
        }
        if self.hdf5 {
            out.extend(
                ["jpeg", "video"]
                    .into_iter()
                    .zip([self.jpeg, self.video])
                    .filter(|(_, held)| !held)
                    .map(|(n, _)| n),
            );
        }
        if !self.transforms {
            out.push("transforms");
        } else if !self.rotations {
            out.push("rotations");
        }
        if !self.mixture {
            out.push("mixture");
        }
        if !self.hierarchy {
            out.push("hierarchy");
        }
        out
    }

    /// What the templates see as `parts`.
    pub fn context(&self) -> PartsContext {
        let backends = [
            ("hdf5", "_Hdf5Backend", self.hdf5),
            ("zarr", "_ZarrBackend", self.zarr),
            ("parquet", "_ParquetBackend", self.parquet),
        ];
        PartsContext {
            parts: *self,
            images: self.cameras,
            stored: self.jpeg || self.video,
            tables: self.frames || self.jpeg || self.video,
            names: self
                .named()
                .into_iter()
                .filter(|(_, held)| *held)
                .map(|(name, _)| name)
                .collect(),
            backends: backends
                .into_iter()
                .filter(|(.., held)| *held)
                .map(|(format, class, _)| (format, class))
                .collect(),
            lacking: self.lacking(),
            every: *self == Parts::every(),
        }
    }
}

/// [`Parts`] as the templates read it: each part's flag, and what follows from them.
#[derive(Debug, Clone, Serialize)]
pub struct PartsContext {
    #[serde(flatten)]
    parts: Parts,
    /// Any camera.
    images: bool,
    /// HDF5 cameras decoded on read (JPEG or video).
    stored: bool,
    /// HDF5 frame tables: the cameras read frame by frame, from byte offsets (`frames`) or
    /// decoded (`stored`).
    tables: bool,
    /// The parts held, by name, in file order.
    names: Vec<&'static str>,
    /// (`data_format`, backend class) of each storage format read.
    backends: Vec<(&'static str, &'static str)>,
    /// [`Parts::lacking`].
    lacking: Vec<&'static str>,
    /// Whether these are [`Parts::every`] part.
    every: bool,
}

impl Serialize for Parts {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let named = self.named();
        let mut map = serializer.serialize_map(Some(named.len()))?;
        for (name, held) in named {
            map.serialize_entry(name, &held)?;
        }
        map.end()
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Part `name`'s flag in `p`.
    fn flag<'a>(p: &'a mut Parts, name: &str) -> &'a mut bool {
        match name {
            "hdf5" => &mut p.hdf5,
            "zarr" => &mut p.zarr,
            "parquet" => &mut p.parquet,
            "cameras" => &mut p.cameras,
            "frames" => &mut p.frames,
            "png" => &mut p.png,
            "mp4" => &mut p.mp4,
            "jpeg" => &mut p.jpeg,
            "video" => &mut p.video,
            "transforms" => &mut p.transforms,
            "rotations" => &mut p.rotations,
            "mixture" => &mut p.mixture,
            "hierarchy" => &mut p.hierarchy,
            "segments" => &mut p.segments,
            "window_stats" => &mut p.window_stats,
            other => panic!("no part {other}"),
        }
    }

    /// Sets of parts to render in tests: none, every one, each alone (with transforms under
    /// rotations), each left out of every.
    pub fn combinations() -> Vec<Parts> {
        let names = Parts::every().named().map(|(name, _)| name);
        let mut out = vec![Parts::default(), Parts::every()];
        for name in names {
            let mut one = Parts::default();
            *flag(&mut one, name) = true;
            one.transforms |= one.rotations;
            one.cameras |= one.frames || one.jpeg || one.video || one.png || one.mp4;
            out.push(one);
            let mut all_but = Parts::every();
            *flag(&mut all_but, name) = false;
            all_but.rotations &= all_but.transforms;
            if !all_but.cameras {
                (all_but.frames, all_but.jpeg, all_but.video) = (false, false, false);
                (all_but.png, all_but.mp4) = (false, false);
            }
            out.push(all_but);
        }
        out
    }

    #[test]
    fn every_part_is_named_once() {
        let every = Parts::every();
        let names: Vec<_> = every.named().iter().map(|(n, _)| *n).collect();
        let mut sorted = names.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), names.len());
        for name in names {
            let mut p = every;
            *flag(&mut p, name) = false;
            assert_ne!(p, every, "{name}");
        }
    }
}
