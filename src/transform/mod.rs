//! Action representations, resolved: a profile's `[[transforms]]` bound to the source's channels
//! (positions, widths, expanded masks), and their math on one row at a time. The build's
//! statistics run them over every training sample ([`Transform::apply`]); the generated loader
//! runs the same math in numpy on read, from `meta.json`'s `transforms` ([`Transform::describe`]).
//!
//! The rules both sides follow: a transform sees the channel as the transforms before it leave
//! it; a reference (the delta's state, the relative pose's current pose) is the reference
//! channel's RAW row at the sample's current step, never transformed first.

use serde::Serialize;
use serde_json::{json, Value};

use crate::rotation::{self, Euler, Layout6d, RotationKind};

mod widths;
pub use widths::Widths;

/// One transform of a profile, bound to the source's channels (manifest positions).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Transform {
    /// The transformed channel: its name and position.
    pub channel: String,
    #[serde(skip)]
    pub channel_index: usize,
    pub op: Op,
    /// The sources of a training mixture it applies to, (position, name) in mixture order;
    /// `None`: every source (always, for one source).
    #[serde(skip)]
    pub sources: Option<Vec<(usize, String)>>,
}

/// What a transform does.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum Op {
    /// `dims` (as the transforms before leave the channel) converted from `from` to `to`.
    Rotation {
        dims: [usize; 2],
        from: RotationKind,
        to: RotationKind,
        #[serde(skip)]
        euler: Option<Euler>,
        convention: Option<String>,
        layout: Layout6d,
    },
    /// `x[..d] -= where(mask, reference[..d], 0)` with `d = mask.len()`.
    Delta {
        reference: String,
        #[serde(skip)]
        reference_index: usize,
        mask: Vec<bool>,
    },
    /// `inv(T_ref) @ T` for the position + rotation slice `dims`.
    RelativePose {
        dims: [usize; 2],
        rotation: RotationKind,
        reference: String,
        #[serde(skip)]
        reference_index: usize,
        reference_dims: [usize; 2],
        reference_rotation: RotationKind,
        to: RotationKind,
        #[serde(skip)]
        euler: Option<Euler>,
        convention: Option<String>,
        layout: Layout6d,
    },
}

impl Transform {
    /// Whether it applies to source `s` (a mixture position; 0 for one source).
    pub fn applies_to(&self, s: usize) -> bool {
        self.sources
            .as_ref()
            .is_none_or(|sources| sources.iter().any(|(i, _)| *i == s))
    }

    /// Whether the transform needs the sample's current step (a reference).
    pub fn per_window(&self) -> bool {
        !matches!(self.op, Op::Rotation { .. })
    }

    /// The reference channel's position, for the per-window transforms.
    pub fn reference(&self) -> Option<usize> {
        match &self.op {
            Op::Rotation { .. } => None,
            Op::Delta {
                reference_index, ..
            }
            | Op::RelativePose {
                reference_index, ..
            } => Some(*reference_index),
        }
    }

    /// The channel's width after this transform, given its width before.
    pub fn width_after(&self, width: usize) -> usize {
        match &self.op {
            Op::Rotation { dims, to, .. } => width - (dims[1] - dims[0]) + to.width(),
            Op::Delta { .. } => width,
            Op::RelativePose { dims, to, .. } => width - (dims[1] - dims[0]) + 3 + to.width(),
        }
    }

    /// `meta.json`'s description, every value explicit (what the generated loader applies).
    pub fn describe(&self) -> Value {
        let mut v = serde_json::to_value(&self.op).expect("a transform serializes");
        v["channel"] = json!(self.channel);
        if let Some(sources) = &self.sources {
            v["sources"] = json!(sources.iter().map(|(_, n)| n).collect::<Vec<_>>());
        }
        v
    }

    /// One line for `chunkc plan` and the dataset card.
    pub fn summary(&self) -> String {
        match &self.sources {
            Some(sources) => {
                let names: Vec<&str> = sources.iter().map(|(_, n)| n.as_str()).collect();
                let which = if names.len() == 1 {
                    "source"
                } else {
                    "sources"
                };
                format!("{}, for {which} {}", self.summary_op(), names.join(", "))
            }
            None => self.summary_op(),
        }
    }

    fn summary_op(&self) -> String {
        let c = &self.channel;
        match &self.op {
            Op::Rotation {
                dims,
                from,
                to,
                layout,
                ..
            } => format!(
                "{c}[{}:{}] {} -> {}{}",
                dims[0],
                dims[1],
                from.name(),
                to.name(),
                six_d(*from, *to, *layout)
            ),
            Op::Delta {
                reference, mask, ..
            } => {
                let d = mask.len();
                let on = mask.iter().filter(|&&b| b).count();
                format!("{c}[:{d}] minus {reference}[:{d}] at the current step ({on} of {d} dims, the rest as they are)")
            }
            Op::RelativePose {
                dims,
                rotation,
                reference,
                reference_dims,
                to,
                layout,
                ..
            } => format!(
                "{c}[{}:{}] relative to {reference}[{}:{}] at the current step ({} -> {}{})",
                dims[0],
                dims[1],
                reference_dims[0],
                reference_dims[1],
                rotation.name(),
                to.name(),
                six_d(*rotation, *to, *layout)
            ),
        }
    }

    /// Applies the transform to one row of the channel (`row` is replaced by the transformed
    /// values); `reference` is the reference channel's raw row at the sample's current step
    /// (empty for a rotation). The error says what is not a rotation.
    pub fn apply(&self, row: &mut Vec<f64>, reference: &[f64]) -> Result<(), String> {
        match &self.op {
            Op::Rotation {
                dims,
                from,
                to,
                euler,
                layout,
                ..
            } => {
                let m = rotation::to_matrix(*from, &row[dims[0]..dims[1]], *euler, *layout)?;
                let mut out = vec![0.0; to.width()];
                rotation::from_matrix(*to, &m, *layout, &mut out);
                row.splice(dims[0]..dims[1], out);
            }
            Op::Delta { mask, .. } => {
                for (d, &on) in mask.iter().enumerate() {
                    if on {
                        row[d] -= reference[d];
                    }
                }
            }
            Op::RelativePose {
                dims,
                rotation: kind,
                reference_dims,
                reference_rotation,
                to,
                euler,
                layout,
                ..
            } => {
                let pose = |v: &[f64], kind: RotationKind| -> Result<_, String> {
                    let p = [v[0], v[1], v[2]];
                    Ok((p, rotation::to_matrix(kind, &v[3..], *euler, *layout)?))
                };
                let (p, r) = pose(&row[dims[0]..dims[1]], *kind)?;
                let (p0, r0) = pose(
                    &reference[reference_dims[0]..reference_dims[1]],
                    *reference_rotation,
                )
                .map_err(|e| format!("the reference holds {e}"))?;
                // inv(T_ref) @ T: p' = R_refᵀ (p - p_ref), R' = R_refᵀ R.
                let inv = rotation::transpose(&r0);
                let p = rotation::apply(&inv, [p[0] - p0[0], p[1] - p0[1], p[2] - p0[2]]);
                let r = rotation::matmul(&inv, &r);
                let mut out = vec![0.0; 3 + to.width()];
                out[..3].copy_from_slice(&p);
                rotation::from_matrix(*to, &r, *layout, &mut out[3..]);
                row.splice(dims[0]..dims[1], out);
            }
        }
        Ok(())
    }
}

/// `, rows` or `, columns` when a side is the 6D representation.
fn six_d(from: RotationKind, to: RotationKind, layout: Layout6d) -> String {
    if from == RotationKind::Rotation6d || to == RotationKind::Rotation6d {
        format!(", {}", layout.name())
    } else {
        String::new()
    }
}

/// The transforms of one channel, in order: its width after them all, given the stored one.
pub fn width_after<'a>(transforms: impl IntoIterator<Item = &'a Transform>, width: usize) -> usize {
    transforms.into_iter().fold(width, |w, t| t.width_after(w))
}

/// `make_bool_mask`: `6` is six `true`, `-1` one `false`.
pub fn expand_mask(mask: &[i64]) -> Vec<bool> {
    mask.iter()
        .flat_map(|&n| std::iter::repeat_n(n > 0, n.unsigned_abs() as usize))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_notation_is_openpis() {
        let m = expand_mask(&[6, -1, 6, -1]);
        assert_eq!(m.len(), 14);
        assert!(m[..6].iter().all(|&b| b) && !m[6] && m[7..13].iter().all(|&b| b) && !m[13]);
    }

    #[test]
    fn delta_and_relative_pose_of_one_row() {
        let delta = Transform {
            channel: "action".into(),
            channel_index: 0,
            sources: None,
            op: Op::Delta {
                reference: "observation.state".into(),
                reference_index: 1,
                mask: expand_mask(&[2, -1]),
            },
        };
        let mut row = vec![5.0, 6.0, 7.0, 8.0];
        delta.apply(&mut row, &[1.0, 2.0, 3.0]).unwrap();
        assert_eq!(row, [4.0, 4.0, 7.0, 8.0]);

        // The pose relative to itself is the identity: zero position, rows of the identity.
        let rel = Transform {
            channel: "action".into(),
            channel_index: 0,
            sources: None,
            op: Op::RelativePose {
                dims: [0, 6],
                rotation: RotationKind::AxisAngle,
                reference: "observation.pose".into(),
                reference_index: 1,
                reference_dims: [0, 6],
                reference_rotation: RotationKind::AxisAngle,
                to: RotationKind::Rotation6d,
                euler: None,
                convention: None,
                layout: Layout6d::Rows,
            },
        };
        let pose = [0.1, 0.2, 0.3, 0.4, -0.5, 0.6];
        let mut row = pose.to_vec();
        row.push(1.0);
        rel.apply(&mut row, &pose).unwrap();
        assert_eq!(row.len(), 10);
        let expect = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0];
        assert!(
            row.iter().zip(expect).all(|(a, b)| (a - b).abs() < 1e-12),
            "{row:?}"
        );
    }
}
