//! GR00T's modality of a `groot` profile, resolved against the channels: per dataset (one per
//! source of a mixture, which GR00T mixes itself), its state and action parts with their
//! columns and slices, its video keys, and the action parts made relative. The spec's checks
//! found overlaps and gaps; here a part past its channel's width, a tiling that stops short of
//! it, names two parts share, and relative actions without a state part to subtract.

use serde::Serialize;

use super::ProfileChannel;
use crate::error::{Error, Result};
use crate::source::{ChannelKind, Manifest};
use crate::spec::modality::{default_part, problems, Parts};
use crate::spec::{LoadedSpec, Preset, Profile};
use crate::transform::Widths;

/// The annotation GR00T's language modality reads the task from (`meta/modality.json`'s
/// `annotation` key; `annotation.human.task_description` in its modality config).
pub const TASK_ANNOTATION: &str = "human.task_description";

/// GR00T's `meta/modality.json` of one dataset, and its relative action parts.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct GrootModality {
    /// The state parts: every low-dimensional channel's but `action`'s, channel by channel.
    pub state: Vec<GrootPart>,
    pub action: Vec<GrootPart>,
    /// (video key, camera channel).
    pub video: Vec<(String, String)>,
    /// The action parts GR00T makes relative to the state part of the same name.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub relative_actions: Vec<String>,
}

/// One part: `[start, end)` of `channel`'s vector, GR00T's `start`, `end` and `original_key`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct GrootPart {
    pub name: String,
    pub channel: String,
    pub start: usize,
    pub end: usize,
}

impl GrootModality {
    /// One line for `chunkc plan`: `state arms 0..14, hands 14..26 (observation.state);
    /// action ...; video top; relative arms`.
    pub fn summary(&self) -> String {
        let parts = |parts: &[GrootPart]| -> String {
            let each: Vec<String> = (parts.iter())
                .map(|p| format!("{} {}..{} ({})", p.name, p.start, p.end, p.channel))
                .collect();
            each.join(", ")
        };
        let mut out = format!(
            "state {}; action {}",
            parts(&self.state),
            parts(&self.action)
        );
        if !self.video.is_empty() {
            let keys: Vec<&str> = self.video.iter().map(|(k, _)| k.as_str()).collect();
            out += &format!("; video {}", keys.join(", "));
        }
        if !self.relative_actions.is_empty() {
            out += &format!("; relative {}", self.relative_actions.join(", "));
        }
        out
    }

    /// The state part named `name`.
    pub fn state_part(&self, name: &str) -> Option<&GrootPart> {
        self.state.iter().find(|p| p.name == name)
    }

    pub fn action_part(&self, name: &str) -> Option<&GrootPart> {
        self.action.iter().find(|p| p.name == name)
    }
}

/// Where an error of one dataset's modality points, and the source it is about.
struct At<'a> {
    spec: &'a LoadedSpec,
    profile: &'a str,
    /// `" (source `sim`)"` in a mixture, else empty.
    source: String,
}

impl At<'_> {
    fn error(&self, path: &[&str], message: String, help: Option<String>) -> Error {
        let mut key = vec!["profiles", self.profile];
        key.extend_from_slice(path);
        let message = format!("profile `{}`{}: {message}", self.profile, self.source);
        self.spec.error_at(&key, message, help)
    }
}

/// Each dataset's modality (one per source, in mixture order); empty unless the profile is a
/// `groot` one.
pub(super) fn resolve(
    spec: &LoadedSpec,
    manifest: &Manifest,
    profile: &Profile,
    channels: &[ProfileChannel],
    widths: &[Widths],
) -> Result<Vec<GrootModality>> {
    if profile.preset != Some(Preset::Groot) {
        return Ok(Vec::new());
    }
    let cameras = channels.iter().any(|c| c.kind == ChannelKind::Image);
    if cameras && profile.image_encoding != Some(crate::spec::ImageEncoding::Video) {
        let at = At {
            spec,
            profile: &profile.name,
            source: String::new(),
        };
        return Err(at.error(
            &["image_encoding"],
            "GR00T decodes cameras from one mp4 per episode; PNG frames in the parquet rows \
             are not read"
                .into(),
            Some("leave `image_encoding` out: the preset's is `video`".into()),
        ));
    }
    for channel in profile.modality.keys() {
        let at = At {
            spec,
            profile: &profile.name,
            source: String::new(),
        };
        match channels.iter().find(|c| &c.name == channel) {
            Some(c) if c.kind == ChannelKind::Image => {
                return Err(at.error(
                    &["modality", channel],
                    format!(
                        "`{channel}` is a camera: GR00T's video key `{}` has no parts",
                        default_part(channel)
                    ),
                    Some("name the parts of low-dimensional channels only".into()),
                ))
            }
            Some(_) => {}
            None => {
                return Err(at.error(
                    &["modality", channel],
                    format!("`modality` names `{channel}`, which the profile does not have"),
                    None,
                ))
            }
        }
    }
    let sources = widths.first().map_or(1, |w| w.own.len().max(1));
    (0..sources)
        .map(|s| {
            let at = At {
                spec,
                profile: &profile.name,
                source: match manifest.parts.get(s) {
                    Some(part) if sources > 1 => format!(" (source `{}`)", part.name),
                    _ => String::new(),
                },
            };
            one(&at, profile, channels, widths, s)
        })
        .collect()
}

/// Source `s`'s modality.
fn one(
    at: &At,
    profile: &Profile,
    channels: &[ProfileChannel],
    widths: &[Widths],
    s: usize,
) -> Result<GrootModality> {
    let mut m = GrootModality {
        state: Vec::new(),
        action: Vec::new(),
        video: Vec::new(),
        relative_actions: profile.relative_actions.clone(),
    };
    for (c, ch) in channels.iter().enumerate() {
        if ch.kind == ChannelKind::Image {
            let key = default_part(&ch.name).to_string();
            if m.video.iter().any(|(k, _)| *k == key) {
                return Err(at.error(
                    &["preset"],
                    format!(
                        "cameras `{}` and `{}` would both be GR00T's video key `{key}`",
                        ch.name,
                        m.video
                            .iter()
                            .find(|(k, _)| *k == key)
                            .map_or("", |(_, c)| c.as_str())
                    ),
                    Some("rename one in `[source.channels]`".into()),
                ));
            }
            m.video.push((key, ch.name.clone()));
            continue;
        }
        let width = widths
            .get(c)
            .and_then(|w| w.own.get(s))
            .copied()
            .unwrap_or(0);
        if width == 0 {
            continue;
        }
        let parts = parts_of(at, profile, ch, width)?;
        let group = if ch.name == "action" {
            &mut m.action
        } else {
            &mut m.state
        };
        for (name, start, end) in parts {
            if let Some(other) = group.iter().find(|p| p.name == name) {
                let path: Vec<&str> = match profile.modality.get(&ch.name) {
                    Some(_) => vec!["modality", &ch.name, &name],
                    None => vec!["modality"],
                };
                return Err(at.error(
                    &path,
                    format!(
                        "`{}` and `{}` both have a part named `{name}`; GR00T's state keys are \
                         one namespace",
                        other.channel, ch.name
                    ),
                    Some(format!(
                        "name the parts of `{}` in `[profiles.{}.modality]`",
                        ch.name, profile.name
                    )),
                ));
            }
            group.push(GrootPart {
                name,
                channel: ch.name.clone(),
                start,
                end,
            });
        }
    }
    relative(at, &m)?;
    Ok(m)
}

/// Each relative action part has a state part of the same name and width to subtract.
fn relative(at: &At, m: &GrootModality) -> Result<()> {
    for name in &m.relative_actions {
        let action = m.action_part(name);
        let state = m.state_part(name);
        let problem = match (action, state) {
            (None, _) => Some(format!(
                "`relative_actions` names `{name}`, which is not an action part (the action's \
                 parts: {})",
                names(&m.action)
            )),
            (Some(_), None) => Some(format!(
                "`relative_actions` names `{name}`, and there is no state part `{name}` to make \
                 it relative to (GR00T subtracts the state part of the same name; the state's \
                 parts: {})",
                names(&m.state)
            )),
            (Some(a), Some(st)) if a.end - a.start != st.end - st.start => Some(format!(
                "relative action `{name}` has {} dimensions and state part `{name}` {}",
                a.end - a.start,
                st.end - st.start
            )),
            _ => None,
        };
        if let Some(message) = problem {
            return Err(at.error(&["relative_actions"], message, None));
        }
    }
    Ok(())
}

/// The parts of low-dimensional channel `ch`, `width` wide (its own in a mixture source), in
/// order: as named in `modality`, else one.
fn parts_of(
    at: &At,
    profile: &Profile,
    ch: &ProfileChannel,
    width: usize,
) -> Result<Vec<(String, usize, usize)>> {
    if ch.shape.len() > 1 {
        return Err(at.error(
            &["preset"],
            format!(
                "GR00T slices vectors, and `{}` holds a {:?} array per step",
                ch.name, ch.shape
            ),
            Some(format!("leave `{}` out of `[source.channels]`", ch.name)),
        ));
    }
    Ok(match profile.modality.get(&ch.name) {
        Some(parts) => tiled(at, &ch.name, parts, width)?,
        None => vec![(default_part(&ch.name).to_string(), 0, width)],
    })
}

/// The parts of `channel`, `width` wide, in order; an error at the first problem.
fn tiled(
    at: &At,
    channel: &str,
    parts: &Parts,
    width: usize,
) -> Result<Vec<(String, usize, usize)>> {
    if let Some(p) = problems(channel, parts, Some(width as u32))
        .into_iter()
        .next()
    {
        let help = Some(format!(
            "the parts of `{channel}` are `[start, end)` slices that tile 0..{width}"
        ));
        return Err(at.error(&["modality", channel, &p.part], p.message, help));
    }
    Ok(crate::spec::modality::ordered(parts)
        .into_iter()
        .map(|(name, start, end)| (name.to_string(), start as usize, end as usize))
        .collect())
}

fn names(parts: &[GrootPart]) -> String {
    let names: Vec<String> = parts.iter().map(|p| format!("`{}`", p.name)).collect();
    if names.is_empty() {
        "none".into()
    } else {
        names.join(", ")
    }
}
