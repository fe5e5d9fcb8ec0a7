//! A channel's widths through a profile's transforms, per source: a training mixture's sources
//! each transform their own dimensions (the stored row's first `own` values) with the transforms
//! that apply to them, and the results are zero-padded to one width again. One source is a
//! mixture of one whose own width is the stored width.

use super::Transform;

/// One channel's widths (values per step).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Widths {
    /// As stored: a mixture's padded width.
    pub stored: usize,
    /// As samples and statistics hold it, after the transforms (what normalization covers).
    pub after: usize,
    /// Per source (mixture order; one entry for one source): its own dimensions before its
    /// transforms (0 where it lacks the channel).
    pub own: Vec<usize>,
    /// Per source: its own dimensions after its transforms.
    pub own_after: Vec<usize>,
}

impl Widths {
    /// Channel `c`'s widths through `transforms` (every channel's, in order), for sources whose
    /// own widths are `own` and a channel stored `stored` wide. `Err((source, width))`: a padded
    /// channel that a source's transforms make wider than its stored width, or sources of an
    /// unpadded channel that its transforms leave at different widths (the first that differs).
    pub fn of(
        transforms: &[Transform],
        c: usize,
        stored: usize,
        own: &[usize],
    ) -> Result<Widths, (usize, usize)> {
        let own_after: Vec<usize> = own
            .iter()
            .enumerate()
            .map(|(s, &w)| {
                let mine = transforms
                    .iter()
                    .filter(|t| t.channel_index == c && t.applies_to(s));
                if w == 0 {
                    0
                } else {
                    super::width_after(mine, w)
                }
            })
            .collect();
        let padded = own.iter().any(|&w| w != stored);
        let after = if padded {
            if let Some(s) = own_after.iter().position(|&w| w > stored) {
                return Err((s, own_after[s]));
            }
            stored
        } else {
            let first = own_after.first().copied().unwrap_or(stored);
            if let Some(s) = own_after.iter().position(|&w| w != first) {
                return Err((s, own_after[s]));
            }
            first
        };
        Ok(Widths {
            stored,
            after,
            own: own.to_vec(),
            own_after,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotation::{Layout6d, RotationKind};
    use crate::transform::Op;

    /// Axis-angle -> 6D on dims [3, 6) of channel 0, for the sources given.
    fn to_6d(sources: Option<Vec<(usize, String)>>) -> Transform {
        Transform {
            channel: "action".into(),
            channel_index: 0,
            sources,
            op: Op::Rotation {
                dims: [3, 6],
                from: RotationKind::AxisAngle,
                to: RotationKind::Rotation6d,
                euler: None,
                convention: None,
                layout: Layout6d::Rows,
            },
        }
    }

    #[test]
    fn one_source_is_the_stored_width_through_its_transforms() {
        let w = Widths::of(&[to_6d(None)], 0, 7, &[7]).unwrap();
        assert_eq!((w.after, w.own_after.as_slice()), (10, &[10][..]));
    }

    #[test]
    fn a_padded_channel_keeps_its_width_and_each_source_its_own() {
        let t = to_6d(Some(vec![(0, "arm".into())]));
        let w = Widths::of(std::slice::from_ref(&t), 0, 32, &[7, 26, 0]).unwrap();
        assert_eq!(w.after, 32);
        assert_eq!(w.own_after, [10, 26, 0]);
        // Wider than the padding: the source is named.
        assert_eq!(Widths::of(&[t], 0, 8, &[7, 8]), Err((0, 10)));
    }

    #[test]
    fn unpadded_sources_must_agree_after_their_transforms() {
        let t = to_6d(Some(vec![(1, "b".into())]));
        assert_eq!(
            Widths::of(std::slice::from_ref(&t), 0, 7, &[7, 7]),
            Err((1, 10))
        );
        assert_eq!(Widths::of(&[t], 1, 7, &[7, 7]).unwrap().after, 7);
    }
}
