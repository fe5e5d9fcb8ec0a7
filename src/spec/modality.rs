//! GR00T's `[profiles.<name>.modality]` as written: each low-dimensional channel's named
//! `[start, end)` parts, which must tile the channel, and the name a channel left out gets.
//!
//! The spec's checks know no widths: they find empty parts, overlaps and gaps between parts;
//! the plan, which knows each channel's width, adds a part past the end and dimensions left
//! over after the last part ([`problems`] with a width).

use std::collections::BTreeMap;

/// A channel's parts as written: `[start, end)` by part name.
pub type Parts = BTreeMap<String, [u32; 2]>;

/// One problem with a channel's parts: the part it is found at, and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    pub part: String,
    pub message: String,
    /// The short label under the value.
    pub label: &'static str,
}

/// The parts by start (then end, then name): the order GR00T's slices run in.
pub fn ordered(parts: &Parts) -> Vec<(&str, u32, u32)> {
    let mut out: Vec<(&str, u32, u32)> = parts
        .iter()
        .map(|(name, &[start, end])| (name.as_str(), start, end))
        .collect();
    out.sort_by_key(|&(name, start, end)| (start, end, name));
    out
}

/// The problems of `channel`'s parts: an empty part, two parts that overlap, dimensions between
/// parts that no part holds; with the channel's `width`, also a part that runs past it and the
/// dimensions after the last part.
pub fn problems(channel: &str, parts: &Parts, width: Option<u32>) -> Vec<Problem> {
    let mut out = Vec::new();
    let mut problem = |part: &str, message: String, label| {
        out.push(Problem {
            part: part.to_string(),
            message,
            label,
        })
    };
    // The end of the dimensions covered so far, and the part that reaches it.
    let mut covered: (u32, Option<&str>) = (0, None);
    for (name, start, end) in ordered(parts) {
        if start >= end {
            problem(
                name,
                format!(
                    "part `{name}` of `{channel}` is [{start}, {end}), which holds no dimension"
                ),
                "empty part",
            );
            continue;
        }
        match covered {
            (at, _) if start > at => problem(
                name,
                format!(
                    "dimensions {at}..{start} of `{channel}` are in no part: the parts must \
                     tile the channel without a gap"
                ),
                "a gap before this part",
            ),
            (at, Some(other)) if start < at => problem(
                name,
                format!(
                    "parts `{other}` and `{name}` of `{channel}` overlap: dimensions \
                     {start}..{} are in both",
                    at.min(end)
                ),
                "overlaps another part",
            ),
            _ => {}
        }
        if let Some(width) = width.filter(|&w| end > w) {
            problem(
                name,
                format!("part `{name}` of `{channel}` ends at {end}, and `{channel}` has {width} dimensions"),
                "past the channel's end",
            );
        }
        if end > covered.0 {
            covered = (end, Some(name));
        }
    }
    if let (Some(width), (at, Some(last))) = (width, covered) {
        if at < width {
            problem(
                last,
                format!(
                    "dimensions {at}..{width} of `{channel}` are in no part: the parts must \
                     tile the channel up to its width, {width}"
                ),
                "the last part ends early",
            );
        }
    }
    out
}

/// The name of the one part of a channel whose parts are not given: its last dotted component
/// (`observation.state` -> `state`, `action` -> `action`, `observation.images.top` -> `top`).
pub fn default_part(channel: &str) -> &str {
    channel.rsplit('.').next().unwrap_or(channel)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parts(items: &[(&str, [u32; 2])]) -> Parts {
        items.iter().map(|(n, r)| (n.to_string(), *r)).collect()
    }

    fn labels(ps: &[Problem]) -> Vec<(&str, &str)> {
        ps.iter().map(|p| (p.part.as_str(), p.label)).collect()
    }

    #[test]
    fn parts_that_tile_the_channel_are_fine() {
        let p = parts(&[("gripper", [7, 8]), ("arm", [0, 7])]);
        assert!(problems("s", &p, None).is_empty());
        assert!(problems("s", &p, Some(8)).is_empty());
        assert_eq!(ordered(&p)[0].0, "arm");
    }

    #[test]
    fn overlaps_gaps_and_empty_parts_are_found_at_their_part() {
        let p = parts(&[("arm", [0, 7]), ("gripper", [6, 8])]);
        let found = problems("s", &p, None);
        assert_eq!(labels(&found), [("gripper", "overlaps another part")]);
        assert!(found[0].message.contains("dimensions 6..7 are in both"));
        let p = parts(&[("arm", [0, 6]), ("gripper", [7, 8])]);
        let found = problems("s", &p, None);
        assert_eq!(labels(&found), [("gripper", "a gap before this part")]);
        assert!(found[0].message.contains("dimensions 6..7"));
        let p = parts(&[("arm", [1, 8])]);
        assert_eq!(
            labels(&problems("s", &p, None)),
            [("arm", "a gap before this part")]
        );
        let p = parts(&[("arm", [0, 8]), ("none", [3, 3])]);
        assert_eq!(labels(&problems("s", &p, None)), [("none", "empty part")]);
    }

    #[test]
    fn the_width_finds_a_part_past_the_end_and_a_short_tiling() {
        let p = parts(&[("arm", [0, 7]), ("gripper", [7, 9])]);
        let found = problems("s", &p, Some(8));
        assert_eq!(labels(&found), [("gripper", "past the channel's end")]);
        let p = parts(&[("arm", [0, 7])]);
        let found = problems("s", &p, Some(8));
        assert_eq!(labels(&found), [("arm", "the last part ends early")]);
        assert!(found[0].message.contains("dimensions 7..8"));
    }

    #[test]
    fn a_channel_left_out_is_named_after_its_last_component() {
        assert_eq!(default_part("observation.state"), "state");
        assert_eq!(default_part("action"), "action");
        assert_eq!(default_part("observation.images.top"), "top");
    }
}
