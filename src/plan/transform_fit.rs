//! A training mixture's transforms against each source they apply to: a delta mask, a rotation's
//! dims or a reference fit one robot's channels and not another's, so every transform is checked
//! on each of its sources' own widths (as the transforms before it leave them), and each
//! channel's widths through the transforms are settled here ([`Widths`]).

use super::transform_errors::At;
use crate::error::{Error, Result};
use crate::source::{ChannelKind, Manifest};
use crate::transform::{Op, Transform, Widths};

/// Every transform against the own widths of each source it applies to (nothing to check for
/// one source, whose own widths are the channels'). `first`: the position of `transforms[0]`
/// of the spec in `transforms` (`abs_action`'s come before).
pub(super) fn each_source(
    at: &At,
    manifest: &Manifest,
    transforms: &[Transform],
    first: usize,
) -> Result<()> {
    for (s, part) in manifest.parts.iter().enumerate() {
        let mut widths = part.widths.clone();
        for (k, t) in transforms.iter().enumerate() {
            if !t.applies_to(s) {
                continue;
            }
            let c = t.channel_index;
            let fits = Fit {
                at,
                k: k.checked_sub(first),
                source: &part.name,
                channel: &manifest.channels[c].name,
                own: widths[c],
            };
            fits.check(&t.op, &widths)?;
            widths[c] = t.width_after(widths[c]);
        }
    }
    Ok(())
}

/// One transform on one source.
struct Fit<'a> {
    at: &'a At<'a>,
    /// The transform's position in the spec's `transforms` (`None`: `abs_action`'s).
    k: Option<usize>,
    source: &'a str,
    channel: &'a str,
    /// The source's own width of the channel, as the transforms before leave it.
    own: usize,
}

impl Fit<'_> {
    fn check(&self, op: &Op, widths: &[usize]) -> Result<()> {
        let (source, name, own) = (self.source, self.channel, self.own);
        if own == 0 {
            return Err(self.error(
                "channel",
                format!("source `{source}` has no `{name}` (only the zeros `mixture.pad_to` adds)"),
            ));
        }
        match op {
            Op::Rotation { dims, .. } => self.slice("dims", *dims, own, name),
            Op::Delta {
                mask,
                reference,
                reference_index,
            } => {
                if mask.len() > own {
                    return Err(self.error(
                        "mask",
                        format!(
                            "the mask covers {} dimensions, but source `{source}`'s `{name}` has {own} values per step",
                            mask.len()
                        ),
                    ));
                }
                let r = widths[*reference_index];
                if mask.len() > r {
                    return Err(self.error(
                        "mask",
                        format!(
                            "the mask covers {} dimensions, but source `{source}`'s reference `{reference}` has {r} values per step",
                            mask.len()
                        ),
                    ));
                }
                Ok(())
            }
            Op::RelativePose {
                dims,
                reference,
                reference_index,
                reference_dims,
                ..
            } => {
                self.slice("dims", *dims, own, name)?;
                let r = widths[*reference_index];
                self.slice("reference_dims", *reference_dims, r, reference)
            }
        }
    }

    fn slice(&self, field: &str, dims: [usize; 2], width: usize, name: &str) -> Result<()> {
        if dims[1] <= width {
            return Ok(());
        }
        Err(self.error(
            field,
            format!(
                "[{}, {}) is out of range for source `{}`: its `{name}` has {width} values per step",
                dims[0], dims[1], self.source
            ),
        ))
    }

    fn error(&self, field: &str, message: String) -> Error {
        let message =
            format!("{message}; name the sources this transform fits with `sources = [...]`");
        match self.k {
            Some(i) => self.at.field(i, field, message),
            None => self.at.key(
                &["abs_action"],
                format!("profiles.{}.abs_action: {message}", self.at.profile),
                None,
            ),
        }
    }
}

/// Every channel's widths through the transforms, per source: a padded channel keeps its stored
/// width, an unpadded one must come out of every source's transforms at one width.
pub(super) fn widths(
    at: &At,
    manifest: &Manifest,
    transforms: &[Transform],
    first: usize,
) -> Result<Vec<Widths>> {
    let mut out = Vec::new();
    for (c, ch) in manifest.channels.iter().enumerate() {
        let stored = ch.width();
        let own = manifest.source_widths(c);
        if ch.kind != ChannelKind::Lowdim {
            out.push(Widths {
                stored,
                after: stored,
                own_after: own.clone(),
                own,
            });
            continue;
        }
        let w = Widths::of(transforms, c, stored, &own).map_err(|(s, wide)| {
            let last = transforms
                .iter()
                .rposition(|t| t.channel_index == c && t.applies_to(s))
                .expect("only transforms change a width");
            let source = &manifest.parts[s].name;
            let name = &ch.name;
            let message = match own.iter().any(|&w| w != stored) {
                true => format!(
                    "after its transforms, source `{source}`'s `{name}` is {wide} wide, wider than `mixture.pad_to.{name}` = {stored}"
                ),
                false => format!(
                    "after its transforms, source `{source}`'s `{name}` is {wide} wide and another source's is not: set `mixture.pad_to.{name}` to pad them to one width"
                ),
            };
            match last.checked_sub(first) {
                Some(i) => at.field(i, "channel", message),
                None => at.key(&["abs_action"], message, None),
            }
        })?;
        out.push(w);
    }
    Ok(out)
}
