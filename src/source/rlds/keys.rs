//! The keys the channels may read: `[source.channels]` checked against what `features.json`
//! declares ([`check_paths`]), then every per-step number and image feature as a key, with the
//! dimensions the feature spec leaves open (image sizes, ragged rows) read from the first
//! episode ([`key_infos`], [`first_record`]).

use std::fs::File;

use super::example::{self, Values};
use super::features::{Feature, Kind};
use super::tfrecord;
use crate::error::{Error, Result};
use crate::source::jpeg;
use crate::source::mapping::KeyInfo;
use crate::spec::LoadedSpec;

/// A spec error for a channel path `features.json` does not declare, listing those it does.
pub(super) fn check_paths(spec: &LoadedSpec, declared: &[Feature], shown: &str) -> Result<()> {
    let names: Vec<&str> = declared.iter().map(|f| f.key.as_str()).collect();
    for (name, channel) in &spec.source().channels {
        for key in channel.keys() {
            let at = ["source", "channels", name.as_str()];
            match declared.iter().find(|f| f.key == key) {
                None => {
                    let close = crate::spec::suggest_name(key, &names)
                        .map(|s| format!("did you mean `{s}`?"));
                    return Err(spec.error_at(
                        &at,
                        format!(
                            "channel `{name}` maps to `{key}`, which {shown} does not declare; it declares: {}",
                            names.join(", ")
                        ),
                        close,
                    ));
                }
                Some(f) => {
                    let why = match &f.kind {
                        _ if !f.per_step => Some(
                            "a per-episode feature (not under `steps`); channels are per step"
                                .to_string(),
                        ),
                        Kind::Text => Some(
                            "text; a language instruction is kept as the episode's task".into(),
                        ),
                        Kind::Other(what) => Some(format!("a {what}, which chunkc cannot read")),
                        _ => None,
                    };
                    if let Some(why) = why {
                        return Err(spec.error_at(
                            &at,
                            format!("channel `{name}` maps to `{key}`, which is {why}"),
                            None,
                        ));
                    }
                }
            }
        }
    }
    Ok(())
}

/// The first record of a shard, its length checked against the file's before it is read.
pub(super) fn first_record(file: &File, shown: &str) -> Result<Vec<u8>> {
    let mut header = [0u8; 12];
    use std::os::unix::fs::FileExt;
    file.read_exact_at(&mut header, 0)
        .map_err(|_| Error::source(format!("{shown}: truncated: record 0 at byte offset 0")))?;
    let len = u64::from_le_bytes(header[..8].try_into().expect("8 bytes"));
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    if len.saturating_add(16) > size {
        return Err(Error::source(format!(
            "{shown}: truncated: record 0 at byte offset 0 needs {} bytes, but the file ends after {size}",
            len.saturating_add(16)
        )));
    }
    tfrecord::read_at(file, tfrecord::Record { offset: 0, len }, shown, 0)
}

/// The keys the channels may read: per-step numbers and images, with their per-step shapes
/// (open dimensions from the first episode).
pub(super) fn key_infos(
    declared: &[Feature],
    first: Option<&[u8]>,
    shown: &str,
) -> Result<Vec<KeyInfo>> {
    let example = first.map(example::parse).transpose().map_err(|e| {
        Error::source(format!(
            "{shown}: the first record is not a tf.train.Example: {e}"
        ))
    })?;
    let mut out = Vec::new();
    for f in declared.iter().filter(|f| f.per_step) {
        let shape = match &f.kind {
            Kind::Tensor if f.shape.is_empty() => vec![1],
            Kind::Tensor => f.shape.iter().map(|d| d.unwrap_or(0)).collect(),
            Kind::Image { format } => {
                let mut dims: Vec<Option<usize>> = f.shape.clone();
                if dims.len() != 3 {
                    dims = vec![None, None, Some(3)];
                }
                if dims[0].is_none() || dims[1].is_none() {
                    let frame = example.as_ref().and_then(|e| match e.get(&f.key) {
                        Some(Values::Bytes(b)) => b.first().copied(),
                        _ => None,
                    });
                    if let (Some(frame), "jpeg") = (frame, format.as_str()) {
                        let (h, w) = jpeg::dimensions(frame).map_err(|e| {
                            Error::source(format!("{shown}: `{}` in the first episode: {e}", f.key))
                        })?;
                        dims[0] = Some(h);
                        dims[1] = Some(w);
                    }
                }
                dims.iter().map(|d| d.unwrap_or(0)).collect()
            }
            Kind::Ragged => {
                let rows = example.as_ref().and_then(|e| {
                    match e.get(&format!("{}/ragged_row_lengths_0", f.key)) {
                        Some(Values::Int64(v)) => v.first().copied(),
                        _ => None,
                    }
                });
                let inner: Vec<usize> = f.shape.iter().skip(1).map(|d| d.unwrap_or(1)).collect();
                let mut shape = vec![rows.unwrap_or(0).max(0) as usize];
                shape.extend(inner);
                if shape.len() > 1 {
                    vec![shape.iter().product()]
                } else {
                    shape
                }
            }
            _ => continue,
        };
        out.push(KeyInfo {
            key: f.key.clone(),
            shape,
            dtype: match &f.kind {
                Kind::Image { format } => format.clone(),
                _ => f.dtype.clone(),
            },
        });
    }
    Ok(out)
}
