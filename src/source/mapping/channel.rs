//! One channel of `[source.channels]` checked against the keys a source offers: the keys it
//! names, the columns it selects, its kind and shape, each with its own spec error.

use std::ops::Range;

use super::{KeyInfo, Part, Recipe};
use crate::error::{Error, Result};
use crate::source::{kind_for_shape, ChannelInfo, ChannelKind};
use crate::spec::{ChannelKindSpec, ChannelSpec, ChannelTable, LoadedSpec};

/// One channel of `[source.channels]` being resolved against the source at `place`.
pub(super) struct OneChannel<'a> {
    pub(super) spec: &'a LoadedSpec,
    pub(super) place: &'a str,
    pub(super) name: &'a str,
    pub(super) channel: &'a ChannelSpec,
}

impl OneChannel<'_> {
    /// Where the channel is written in the spec, with `more` below it (`kind`, `columns`).
    fn at<'k>(&'k self, more: &[&'k str]) -> Vec<&'k str> {
        [&["source", "channels", self.name], more].concat()
    }

    fn table(&self) -> Option<&ChannelTable> {
        match self.channel {
            ChannelSpec::Table(t) => Some(t),
            ChannelSpec::Key(_) => None,
        }
    }

    /// The channel's info and recipe; `None` (with a warning) when it has no values per step.
    pub(super) fn resolve(
        &self,
        available: &[KeyInfo],
        warnings: &mut Vec<String>,
    ) -> Result<Option<(ChannelInfo, Recipe)>> {
        let (infos, parts) = self.keys(available, warnings)?;
        let parts = self.columns(parts)?;
        let width: usize = parts.iter().map(|p| p.columns.len()).sum();
        if width == 0 {
            if self.name == "action" {
                return Err(self.spec.error_at(
                    &self.at(&[]),
                    format!(
                        "`action` maps to `{}`, which has no values per step",
                        self.channel.describe()
                    ),
                    None,
                ));
            }
            warnings.push(format!(
                "channel `{}` maps to `{}` in {}, which has zero width; the channel is skipped",
                self.name,
                self.channel.describe(),
                self.place
            ));
            return Ok(None);
        }
        let (kind, shape) = self.kind(&infos, width)?;
        if self.name == "action" && kind != ChannelKind::Lowdim {
            return Err(self.spec.error_at(
                &self.at(&[]),
                format!(
                    "`action` must be a vector per step, but `{}` is {shape:?}",
                    self.channel.describe()
                ),
                None,
            ));
        }
        let mut dtypes: Vec<&str> = infos.iter().map(|k| k.dtype.as_str()).collect();
        dtypes.dedup();
        let info = ChannelInfo {
            name: self.name.to_string(),
            key: self.channel.describe(),
            kind,
            shape,
            source_dtype: dtypes.join("+"),
        };
        Ok(Some((info, Recipe { parts })))
    }

    /// The keys the channel names, each found among `available`, and a part per key with
    /// values (a zero-width key among several is skipped, with a warning).
    fn keys<'k>(
        &self,
        available: &'k [KeyInfo],
        warnings: &mut Vec<String>,
    ) -> Result<(Vec<&'k KeyInfo>, Vec<Part>)> {
        let (name, place) = (self.name, self.place);
        let mut parts = Vec::new();
        let mut infos = Vec::new();
        for key in self.channel.keys() {
            let Some(info) = available.iter().find(|k| k.key == key) else {
                let names: Vec<&str> = available.iter().map(|k| k.key.as_str()).collect();
                let close =
                    crate::spec::suggest_name(key, &names).map(|s| format!("did you mean `{s}`?"));
                return Err(self.spec.error_at(
                    &self.at(&[]),
                    format!(
                        "channel `{name}` maps to `{key}`, which is not in {place}; the source has: {}",
                        names.join(", ")
                    ),
                    close,
                ));
            };
            infos.push(info);
            if info.width() == 0 {
                if self.channel.keys().len() > 1 {
                    warnings.push(format!(
                        "channel `{name}`: `{key}` in {place} has zero width {:?}; it is skipped",
                        info.shape
                    ));
                }
                continue;
            }
            parts.push(Part {
                key: key.to_string(),
                width: info.width(),
                columns: 0..info.width(),
            });
        }
        Ok((infos, parts))
    }

    /// The parts restricted to the channel's `columns`, when it selects some.
    fn columns(&self, parts: Vec<Part>) -> Result<Vec<Part>> {
        let Some([a, b]) = self.table().and_then(|t| t.columns) else {
            return Ok(parts);
        };
        let total: usize = parts.iter().map(|p| p.width).sum();
        if b > total {
            return Err(self.spec.error_at(
                &self.at(&["columns"]),
                format!(
                    "channel `{}` selects columns {a}..{b} of `{}`, which has {total} per step",
                    self.name,
                    self.channel.keys().join(" + ")
                ),
                Some(format!(
                    "columns are `[start, end)` with end at most {total}"
                )),
            ));
        }
        Ok(select(&parts, a..b))
    }

    /// The channel's kind and per-step shape: a whole single key's own (or as declared), else
    /// a vector of `width` (slices and concatenations of vectors only).
    fn kind(&self, infos: &[&KeyInfo], width: usize) -> Result<(ChannelKind, Vec<usize>)> {
        let table = self.table();
        let whole_single_key = infos.len() == 1 && table.is_none_or(|t| t.columns.is_none());
        let declared = table.and_then(|t| t.kind);
        let name = self.name;
        if !whole_single_key {
            if declared == Some(ChannelKindSpec::Image) {
                return Err(self.spec.error_at(
                    &self.at(&["kind"]),
                    format!("channel `{name}` selects columns or concatenates keys, so it cannot be an image"),
                    None,
                ));
            }
            if let Some(image) = infos.iter().find(|k| k.shape.len() == 3 && k.width() > 0) {
                return Err(self.spec.error_at(
                    &self.at(&[]),
                    format!(
                        "channel `{name}` slices or concatenates `{}`, an image of shape {:?}; only vectors can be",
                        image.key, image.shape
                    ),
                    None,
                ));
            }
            return Ok((ChannelKind::Lowdim, vec![width]));
        }
        let shape = infos[0].shape.clone();
        if declared == Some(ChannelKindSpec::Lowdim) {
            return Ok((ChannelKind::Lowdim, vec![width]));
        }
        let kind = kind_for_shape(&shape)
            .map_err(|e| Error::source(format!("{}: `{}`: {e}", self.place, infos[0].key)))?;
        if declared == Some(ChannelKindSpec::Image) && kind != ChannelKind::Image {
            return Err(self.spec.error_at(
                &self.at(&["kind"]),
                format!(
                    "channel `{name}` is declared an image, but `{}` has per-step shape {shape:?}, not (H, W, C)",
                    infos[0].key
                ),
                None,
            ));
        }
        Ok((kind, shape))
    }
}

/// The parts restricted to `range` of their concatenated columns.
fn select(parts: &[Part], range: Range<usize>) -> Vec<Part> {
    let mut out = Vec::new();
    let mut offset = 0;
    for p in parts {
        let n = p.columns.len();
        let lo = range.start.max(offset);
        let hi = range.end.min(offset + n);
        if lo < hi {
            let start = p.columns.start + (lo - offset);
            out.push(Part {
                key: p.key.clone(),
                width: p.width,
                columns: start..start + (hi - lo),
            });
        }
        offset += n;
    }
    out
}
#[cfg(test)]
mod tests {
    use super::*;

    fn part(key: &str, width: usize) -> Part {
        Part {
            key: key.into(),
            width,
            columns: 0..width,
        }
    }

    #[test]
    fn select_spans_parts() {
        let parts = [part("a", 3), part("b", 2)];
        let got = select(&parts, 2..4);
        assert_eq!(got.len(), 2);
        assert_eq!((got[0].key.as_str(), got[0].columns.clone()), ("a", 2..3));
        assert_eq!((got[1].key.as_str(), got[1].columns.clone()), ("b", 0..1));
        assert!(select(&parts, 3..3).is_empty());
    }
}
