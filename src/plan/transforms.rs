//! A profile's action representations checked against the source's channels and bound to them
//! (`[[profiles.<name>.transforms]]`, `abs_action`, `stats_population`): every bad value is a
//! spec error naming its key, at `chunkc check`.

use super::transform_errors::At;
use crate::error::Result;
use crate::rotation::{Euler, RotationKind};
use crate::source::{ChannelKind, Manifest};
use crate::spec::{
    DeltaSpec, LoadedSpec, OutputFormat, Profile, RelativePoseSpec, RotationSpec, StatsPopulation,
    TransformSpec,
};
use crate::transform::{expand_mask, Op, Transform, Widths};
use crate::window::Sampling;

/// The profile's transforms (those of `abs_action` first), bound to the manifest's channels and
/// to the sources they apply to, and every channel's widths through them.
pub(super) fn resolve(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
    sampling: &Sampling,
) -> Result<(Vec<Transform>, Vec<Widths>)> {
    let at = At {
        spec,
        profile: &profile.name,
    };
    let mut out = super::abs_action::transforms(&at, manifest, profile)?;
    // Each channel's width as the transforms so far leave it.
    let mut widths: Vec<usize> = manifest.channels.iter().map(|c| c.width()).collect();
    for t in &out {
        widths[t.channel_index] = t.width_after(widths[t.channel_index]);
    }
    for (i, t) in profile.transforms.iter().enumerate() {
        let c = channel(&at, manifest, i, "channel", t.channel())?;
        let op = match t {
            TransformSpec::Rotation(r) => {
                rotation_op(&at, i, r, widths[c], &manifest.channels[c].name)?
            }
            TransformSpec::Delta(d) => {
                delta_op(&at, manifest, i, d, widths[c], &manifest.channels[c].name)?
            }
            TransformSpec::RelativePose(r) => {
                relative_pose_op(&at, manifest, i, r, widths[c], &manifest.channels[c].name)?
            }
        };
        let t = Transform {
            channel: manifest.channels[c].name.clone(),
            channel_index: c,
            op,
            sources: sources(&at, manifest, i, t.sources())?,
        };
        widths[c] = t.width_after(widths[c]);
        out.push(t);
    }
    population(&at, profile, sampling, &out)?;
    let first = out.len() - profile.transforms.len();
    super::transform_fit::each_source(&at, manifest, &out, first)?;
    let widths = super::transform_fit::widths(&at, manifest, &out, first)?;
    if !out.is_empty()
        && profile.format == OutputFormat::Hdf5
        && profile.layout != crate::spec::Layout::Index
    {
        return Err(at.key(
            &["layout"],
            format!(
                "profiles.{}.layout = \"{}\" stores chunks computed at build time, but the loader applies this profile's transforms on read",
                profile.name,
                profile.layout.name()
            ),
            Some("leave `layout` out (`index`)".into()),
        ));
    }
    Ok((out, widths))
}

/// `transforms[i].sources`: names of the mixture's sources, as (position, name).
fn sources(
    at: &At,
    manifest: &Manifest,
    i: usize,
    names: Option<&[String]>,
) -> Result<Option<Vec<(usize, String)>>> {
    let Some(names) = names else {
        return Ok(None);
    };
    let known: Vec<&str> = manifest.parts.iter().map(|p| p.name.as_str()).collect();
    if known.is_empty() {
        return Err(at.field(
            i,
            "sources",
            "names sources of a training mixture, but this spec has one `[source]`".into(),
        ));
    }
    if names.is_empty() {
        return Err(at.field(
            i,
            "sources",
            format!(
                "is empty: name one of {} or leave `sources` out (every source)",
                known.join(", ")
            ),
        ));
    }
    let mut out: Vec<(usize, String)> = Vec::new();
    for name in names {
        let Some(s) = known.iter().position(|k| k == name) else {
            return Err(at.field(
                i,
                "sources",
                format!(
                    "no source `{name}` (the mixture's sources are {})",
                    known.join(", ")
                ),
            ));
        };
        if !out.iter().any(|(k, _)| *k == s) {
            out.push((s, name.clone()));
        }
    }
    out.sort();
    Ok(Some(out))
}

/// `op = "rotation"` on a channel `width` wide (as the transforms before leave it).
fn rotation_op(at: &At, i: usize, r: &RotationSpec, width: usize, name: &str) -> Result<Op> {
    slice(at, i, "dims", r.dims, width, name)?;
    kind_width(at, i, "from", r.from, r.dims, "")?;
    target(at, i, "to", r.to)?;
    let euler = convention(at, i, r.convention.as_deref(), &[r.from])?;
    Ok(Op::Rotation {
        dims: r.dims,
        from: r.from,
        to: r.to,
        euler,
        convention: r.convention.clone(),
        layout: r.layout.unwrap_or_default(),
    })
}

/// `op = "delta"`: the mask fits the channel and the reference.
fn delta_op(
    at: &At,
    manifest: &Manifest,
    i: usize,
    d: &DeltaSpec,
    width: usize,
    name: &str,
) -> Result<Op> {
    let reference = channel(at, manifest, i, "reference", &d.reference)?;
    let mask = mask(at, i, &d.mask)?;
    if mask.len() > width {
        return Err(at.field(
            i,
            "mask",
            format!(
                "the mask covers {} dimensions, but `{name}` has {width} values per step",
                mask.len()
            ),
        ));
    }
    let ref_width = manifest.channels[reference].width();
    if mask.len() > ref_width {
        return Err(at.field(i, "mask", format!(
            "the mask covers {} dimensions, but the reference `{}` has only {ref_width} values per step",
            mask.len(), d.reference
        )));
    }
    Ok(Op::Delta {
        reference: d.reference.clone(),
        reference_index: reference,
        mask,
    })
}

/// `op = "relative_pose"`: both slices hold a position and a rotation of their kind.
fn relative_pose_op(
    at: &At,
    manifest: &Manifest,
    i: usize,
    r: &RelativePoseSpec,
    width: usize,
    name: &str,
) -> Result<Op> {
    let reference = channel(at, manifest, i, "reference", &r.reference)?;
    let ref_rotation = r.reference_rotation.unwrap_or(r.rotation);
    let to = r.to.unwrap_or(r.rotation);
    slice(at, i, "dims", r.dims, width, name)?;
    kind_width(at, i, "dims", r.rotation, r.dims, "3 (position) + ")?;
    let ref_width = manifest.channels[reference].width();
    slice(
        at,
        i,
        "reference_dims",
        r.reference_dims,
        ref_width,
        &r.reference,
    )?;
    kind_width(
        at,
        i,
        "reference_dims",
        ref_rotation,
        r.reference_dims,
        "3 (position) + ",
    )?;
    target(at, i, "to", to)?;
    let euler = convention(at, i, r.convention.as_deref(), &[r.rotation, ref_rotation])?;
    Ok(Op::RelativePose {
        dims: r.dims,
        rotation: r.rotation,
        reference: r.reference.clone(),
        reference_index: reference,
        reference_dims: r.reference_dims,
        reference_rotation: ref_rotation,
        to,
        euler,
        convention: r.convention.clone(),
        layout: r.layout.unwrap_or_default(),
    })
}

/// A channel named by a transform: one of the source's low-dimensional channels.
fn channel(at: &At, manifest: &Manifest, i: usize, field: &str, name: &str) -> Result<usize> {
    let Some(c) = manifest.channels.iter().position(|c| c.name == name) else {
        let names: Vec<&str> = manifest.channels.iter().map(|c| c.name.as_str()).collect();
        return Err(at.field(
            i,
            field,
            format!(
                "no channel `{name}` in [source.channels] (it maps {})",
                names.join(", ")
            ),
        ));
    };
    if manifest.channels[c].kind != ChannelKind::Lowdim {
        return Err(at.field(
            i,
            field,
            format!("`{name}` is an image; transforms apply to low-dimensional channels"),
        ));
    }
    Ok(c)
}

/// `[start, end)` within a channel of `width` values per step.
fn slice(at: &At, i: usize, field: &str, dims: [usize; 2], width: usize, name: &str) -> Result<()> {
    if dims[0] >= dims[1] || dims[1] > width {
        return Err(at.field(
            i,
            field,
            format!(
                "[{}, {}) is out of range: `{name}` has {width} values per step here (a half-open [start, end) with start < end <= {width})",
                dims[0], dims[1]
            ),
        ));
    }
    Ok(())
}

/// The slice holds `prefix` + one rotation of `kind`.
fn kind_width(
    at: &At,
    i: usize,
    field: &str,
    kind: RotationKind,
    dims: [usize; 2],
    prefix: &str,
) -> Result<()> {
    let offset = if prefix.is_empty() { 0 } else { 3 };
    let want = offset + kind.width();
    if dims[1] - dims[0] != want {
        return Err(at.field(
            i,
            field,
            format!(
                "[{}, {}) holds {} values, but {prefix}{} is {} wide ({want} in all)",
                dims[0],
                dims[1],
                dims[1] - dims[0],
                kind.name(),
                kind.width()
            ),
        ));
    }
    Ok(())
}

fn target(at: &At, i: usize, field: &str, kind: RotationKind) -> Result<()> {
    if kind == RotationKind::Euler {
        return Err(at.field(
            i,
            field,
            "Euler angles are not a conversion target (a discontinuous representation to train on); use rotation_6d, a quaternion, axis_angle or matrix".into(),
        ));
    }
    Ok(())
}

/// The Euler sequence, required (and only allowed) when a rotation is `euler`.
fn convention(
    at: &At,
    i: usize,
    seq: Option<&str>,
    kinds: &[RotationKind],
) -> Result<Option<Euler>> {
    let euler = kinds.contains(&RotationKind::Euler);
    match (seq, euler) {
        (None, true) => Err(at.field(i, "convention", "Euler angles need their axis sequence, e.g. `convention = \"xyz\"` (scipy's `seq`: lowercase extrinsic, uppercase intrinsic)".into())),
        (Some(_), false) => Err(at.field(i, "convention", "only Euler angles take a convention".into())),
        (Some(s), true) => Euler::parse(s).map(Some).map_err(|m| at.field(i, "convention", m)),
        (None, false) => Ok(None),
    }
}

/// openpi's `make_bool_mask` notation, expanded.
fn mask(at: &At, i: usize, mask: &[i64]) -> Result<Vec<bool>> {
    if mask.is_empty() || mask.contains(&0) {
        return Err(at.field(i, "mask", "a mask is a list of nonzero counts, as openpi's make_bool_mask takes them: `6` for six dimensions made relative, `-1` for one left as it is".into()));
    }
    Ok(expand_mask(mask))
}

/// `stats_population`: windows need fixed windows; a per-window transform needs windows.
fn population(
    at: &At,
    profile: &Profile,
    sampling: &Sampling,
    transforms: &[Transform],
) -> Result<()> {
    let windowed = transforms.iter().any(Transform::per_window);
    if windowed && !matches!(sampling, Sampling::Window { .. }) {
        return Err(at.key(
            &["transforms"],
            format!(
                "profiles.{}: delta and relative_pose transforms need fixed windows, not {} sampling",
                profile.name,
                sampling.name()
            ),
            None,
        ));
    }
    match profile.stats_population {
        StatsPopulation::Windows if !matches!(sampling, Sampling::Window { .. }) => Err(at.key(
            &["stats_population"],
            format!(
                "profiles.{}.stats_population = \"windows\" needs fixed windows, not {} sampling",
                profile.name,
                sampling.name()
            ),
            None,
        )),
        StatsPopulation::Frames if windowed => Err(at.key(
            &["stats_population"],
            format!(
                "profiles.{}.stats_population = \"frames\": a delta or relative_pose transform depends on the sample's current step, so its statistics are over windows",
                profile.name
            ),
            Some("leave `stats_population` out, or set it to \"windows\"".into()),
        )),
        _ => Ok(()),
    }
}
