//! Each LeRobot camera opened as the build will open it (its videos are files of their own).
//!
//! A camera whose videos all open is mapped. One whose videos are missing for some episodes is
//! mapped too, with `[audit] video = "exclude_episode"` in the spec, which leaves those episodes
//! out, and a comment that lists them ([`MissingVideos`]): a policy trained on the camera is
//! usually worth a few episodes. A camera that cannot be read at all (every video missing, a
//! feature chunkc cannot read) is left out, as a commented line with the reason.

use std::path::Path;

use serde::Serialize;

use super::key_role::KeyRole;
use super::text::{self, Draft};
use crate::audit;
use crate::error::Result;
use crate::source;

/// The most episode ids a comment lists; more are counted.
const LISTED: usize = 60;

/// A camera kept although some episodes have no video file for it: the spec excludes them.
#[derive(Debug, Clone, Serialize)]
pub struct MissingVideos {
    /// The channel the spec maps the camera to.
    pub channel: String,
    /// The source's feature.
    pub key: String,
    /// The source ids of the episodes without its video, ascending.
    pub episodes: Vec<u64>,
    /// How many episodes the source has.
    pub of: usize,
}

impl MissingVideos {
    /// `7 of 50 episodes have no video: 1, 2, 7, 9, 25, 33, 34`.
    pub fn sentence(&self) -> String {
        let mut ids: Vec<String> = self
            .episodes
            .iter()
            .take(LISTED)
            .map(u64::to_string)
            .collect();
        if self.episodes.len() > LISTED {
            ids.push(format!("… ({} more)", self.episodes.len() - LISTED));
        }
        let n = self.episodes.len();
        format!(
            "{n} of {} episode{} {} no video: {}",
            self.of,
            if self.of == 1 { "" } else { "s" },
            if n == 1 { "has" } else { "have" },
            ids.join(", ")
        )
    }
}

/// Opens each mapped camera beside the action: a camera that opens stays as it is; one whose
/// videos are missing for some episodes stays, noted, and is returned; any other is unmapped
/// (`suggested` keeps its name for the commented line), its note the first line of the reason.
pub fn check(
    roles: &mut [KeyRole],
    action: &KeyRole,
    draft: &Draft,
    spec_dir: &Path,
) -> Result<Vec<MissingVideos>> {
    let mut missing = Vec::new();
    for r in roles.iter_mut().filter(|r| r.role.is_camera()) {
        let Some(channel) = r.channel.clone() else {
            continue;
        };
        let pair = vec![
            text::mapping_of(action),
            (channel.clone(), r.key.clone(), None),
        ];
        let trial = super::parse(
            &draft.render_minimal(&pair),
            spec_dir,
            "(init camera check)",
        )?;
        let Err(e) = source::open(&trial) else {
            continue;
        };
        let reason = e.to_string();
        let reason = reason.lines().next().unwrap_or("").to_string();
        match without_videos(r, &pair, draft, spec_dir)? {
            Some(m) if m.episodes.len() < m.of => {
                r.note = Some(format!(
                    "{}; excluded by `[audit] video = \"exclude_episode\"` (delete this line and that key to keep every episode, without the camera)",
                    m.sentence()
                ));
                missing.push(MissingVideos { channel, ..m });
            }
            Some(m) => {
                r.suggested = r.channel.take();
                r.note = Some(format!(
                    "left out: none of the {} episode(s) has its video file (first missing: {})",
                    m.of,
                    first_missing(&reason)
                ));
            }
            None => {
                r.suggested = r.channel.take();
                r.note = Some(format!("left out: {reason}"));
            }
        }
    }
    Ok(missing)
}

/// The file a missing-video error names, or the whole reason.
fn first_missing(reason: &str) -> &str {
    reason
        .split_once(", file ")
        .and_then(|(_, rest)| rest.split_once(": "))
        .map(|(file, _)| file)
        .unwrap_or(reason)
}

/// The episodes whose video file of camera `r` is missing, when the source opens with those
/// episodes excluded; `None` when it does not open even so (the camera fails for another reason)
/// or no file is missing.
fn without_videos(
    r: &KeyRole,
    pair: &[text::Mapping],
    draft: &Draft,
    spec_dir: &Path,
) -> Result<Option<MissingVideos>> {
    let excluding = draft.excluding_bad_videos(true);
    let trial = super::parse(
        &excluding.render_minimal(pair),
        spec_dir,
        "(init camera check)",
    )?;
    let Ok(opened) = source::open(&trial) else {
        return Ok(None);
    };
    let Ok((report, _)) = audit::run(&trial, opened.as_ref(), false) else {
        return Ok(None);
    };
    let mut episodes: Vec<u64> = report
        .video
        .iter()
        .filter(|v| v.check.camera == r.key && !draft.path.join(&v.check.file).exists())
        .map(|v| v.episode)
        .collect();
    episodes.sort_unstable();
    episodes.dedup();
    if episodes.is_empty() {
        return Ok(None);
    }
    Ok(Some(MissingVideos {
        channel: String::new(),
        key: r.key.clone(),
        episodes,
        of: opened.manifest().episodes.len(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sentence_counts_and_lists() {
        let m = MissingVideos {
            channel: "observation.image".into(),
            key: "image".into(),
            episodes: vec![1, 2, 7, 9, 25, 33, 34],
            of: 50,
        };
        assert_eq!(
            m.sentence(),
            "7 of 50 episodes have no video: 1, 2, 7, 9, 25, 33, 34"
        );
        let one = MissingVideos {
            episodes: vec![1],
            of: 3,
            ..m.clone()
        };
        assert_eq!(one.sentence(), "1 of 3 episodes has no video: 1");
        let many = MissingVideos {
            episodes: (0..100).collect(),
            of: 200,
            ..m
        };
        assert!(many.sentence().ends_with("59, … (40 more)"));
    }

    #[test]
    fn the_missing_file_is_named() {
        let reason = "set: episode 1, camera `image` (channel `observation.image`), file videos/a.mp4: the file is missing; set …";
        assert_eq!(first_missing(reason), "videos/a.mp4");
        assert_eq!(first_missing("other"), "other");
    }
}
