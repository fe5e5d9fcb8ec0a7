//! Reading an RLDS episode: its one record read again by offset, the channels assembled from
//! its features, JPEG frames decoded as TensorFlow does ([`super::image`]).

use super::example::{self, Values};
use super::features::Kind;
use super::{image, tfrecord, RldsSource};
use crate::error::{Error, Result};
use crate::source::mapping::{self, Raw};
use crate::source::{Episode, Manifest, Source};

impl Source for RldsSource {
    fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    fn read_episode(&self, index: usize) -> Result<Episode> {
        self.read(index, true)
    }

    /// The low-dim channels only: no JPEG is decoded (the doctor reads every episode's low-dim
    /// values before the build).
    fn read_lowdim(&self, index: usize, channels: &[usize]) -> Result<Vec<Vec<f32>>> {
        Ok(self.read(index, false)?.take_lowdim(channels))
    }
}

impl RldsSource {
    /// The episode at `index`; without `decode_images`, its frames are zeros of the right size
    /// (for a caller that keeps only the low-dim values).
    fn read(&self, index: usize, decode_images: bool) -> Result<Episode> {
        let info = &self.manifest.episodes[index];
        let p = self.places[index];
        let (shown, file) = &self.shards[p.shard];
        let place = format!("{shown}: record {} (episode {})", p.record, info.id);
        let data = tfrecord::read_at(file, p.at, shown, p.record)?;
        let ex = example::parse(&data)
            .map_err(|e| Error::source(format!("{place}: not a tf.train.Example: {e}")))?;
        let len = info.len;
        let channels = mapping::assemble(&self.mapped, len, &place, |key| {
            let f = &self.read[key];
            let stored = match f.kind {
                Kind::Ragged => format!("{key}/ragged_flat_values"),
                _ => key.to_string(),
            };
            match (&f.kind, ex.get(&stored)) {
                (Kind::Image { .. }, Some(Values::Bytes(_))) if !decode_images => {
                    let shape = self.manifest_shape(key);
                    Ok(Raw::U8(vec![0u8; len * shape.iter().product::<usize>()]))
                }
                (Kind::Image { .. }, Some(Values::Bytes(frames))) => {
                    let info = self.manifest_shape(key);
                    let (h, w, c) = (info[0], info[1], info[2]);
                    let mut out = Vec::with_capacity(len * h * w * c);
                    for (t, frame) in frames.iter().enumerate() {
                        let (fh, fw) = image::decode_jpeg_tf(frame, c, &mut out).map_err(|e| {
                            Error::source(format!("{place}: `{key}` step {t}: {e}"))
                        })?;
                        if (fh, fw) != (h, w) {
                            return Err(Error::source(format!(
                                "{place}: `{key}` step {t} is {fh}x{fw}, but the channel's frames are {h}x{w}"
                            )));
                        }
                    }
                    Ok(Raw::U8(out))
                }
                (_, Some(Values::Float(v))) => Ok(Raw::F32(v.clone())),
                (_, Some(Values::Int64(v))) => Ok(Raw::F32(v.iter().map(|&x| x as f32).collect())),
                (_, Some(Values::Bytes(v))) if v.is_empty() => Ok(Raw::F32(Vec::new())),
                _ => Err(Error::source(format!(
                    "{place}: `{key}` changed since the dataset was opened"
                ))),
            }
        })?;
        Ok(Episode {
            id: info.id,
            len,
            timestamps: None,
            channels,
            packets: Default::default(),
        })
    }

    /// The per-step shape of an image key, as the mapping resolved it.
    fn manifest_shape(&self, key: &str) -> Vec<usize> {
        self.manifest
            .channels
            .iter()
            .find(|c| c.key == key)
            .map(|c| c.shape.clone())
            .unwrap_or_else(|| {
                let f = &self.read[key];
                f.shape.iter().map(|d| d.unwrap_or(0)).collect()
            })
    }
}
