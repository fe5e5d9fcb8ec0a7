//! `lerobot_version`: which LeRobot layout a `format = "parquet"` profile writes, resolved along
//! the `extends` chain (the nearest profile that sets it; else `v3.0`). Presets set none.

use std::collections::BTreeMap;

use super::model::{LerobotVersion, ProfileSpec};

/// The value of profile `name`: its own, else the nearest profile it extends that sets one, else
/// the default (`v3.0`). A chain that is broken or goes round (reported by the expansion) ends
/// where it breaks.
pub fn resolve(name: &str, profiles: &BTreeMap<String, ProfileSpec>) -> LerobotVersion {
    set_at(name, profiles).map_or(LerobotVersion::V30, |(_, v)| v)
}

/// The profile of the chain that sets `lerobot_version`, and the value; `None` when none does.
pub fn set_at<'a>(
    name: &'a str,
    profiles: &'a BTreeMap<String, ProfileSpec>,
) -> Option<(&'a str, LerobotVersion)> {
    let mut current = name;
    for _ in 0..=profiles.len() {
        let spec = profiles.get(current)?;
        if let Some(v) = spec.lerobot_version {
            return Some((current, v));
        }
        current = spec.extends.as_deref()?;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_profile_that_sets_it_wins() {
        let spec = |v: Option<LerobotVersion>, extends: Option<&str>| ProfileSpec {
            lerobot_version: v,
            extends: extends.map(str::to_string),
            ..Default::default()
        };
        let profiles: BTreeMap<String, ProfileSpec> = [
            ("base".to_string(), spec(Some(LerobotVersion::V21), None)),
            ("child".to_string(), spec(None, Some("base"))),
            (
                "own".to_string(),
                spec(Some(LerobotVersion::V30), Some("base")),
            ),
            ("plain".to_string(), spec(None, None)),
            ("loop".to_string(), spec(None, Some("loop"))),
        ]
        .into();
        assert_eq!(resolve("child", &profiles), LerobotVersion::V21);
        assert_eq!(
            set_at("child", &profiles),
            Some(("base", LerobotVersion::V21))
        );
        assert_eq!(resolve("own", &profiles), LerobotVersion::V30);
        assert_eq!(resolve("plain", &profiles), LerobotVersion::V30);
        assert_eq!(resolve("loop", &profiles), LerobotVersion::V30);
    }
}
