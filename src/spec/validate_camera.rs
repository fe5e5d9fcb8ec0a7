//! The checks of `[profiles.<name>.cameras.<channel>]` that need no source: the camera is a
//! channel of `[source.channels]`, and `size` is `[H, W]`, two positive integers. Whether the
//! channel holds images, and whether `size` enlarges its frames, need the source: the plan
//! checks those (`plan::cameras`).

use super::diagnostic::{did_you_mean, Diagnostic};
use super::load::{dotted, LoadedSpec, Target};
use super::model::ProfileSpec;

/// Every problem with the cameras profile `name` sets itself (inherited ones are reported at the
/// profile that sets them).
pub(super) fn check(loaded: &LoadedSpec, name: &str, own: &ProfileSpec) -> Vec<Diagnostic> {
    let mut found = Vec::new();
    let Some(cameras) = &own.cameras else {
        return found;
    };
    let channels: Vec<&str> = loaded.channel_map().into_keys().collect();
    for (camera, spec) in cameras {
        let at = ["profiles", name, "cameras", camera.as_str()];
        if !channels.contains(&camera.as_str()) {
            let message = format!(
                "`{}` names `{camera}`, which is not a channel in `[source.channels]`",
                dotted(&at[..3])
            );
            let help = did_you_mean(camera, &channels, "channel");
            let d = loaded.diagnostic(&at, Target::Key, message, "unknown channel");
            found.push(d.with_help(help));
        }
        if spec.size_hw().is_none() {
            let size = ["profiles", name, "cameras", camera.as_str(), "size"];
            let given: Vec<String> = spec.size.iter().map(i64::to_string).collect();
            let message = format!(
                "`{}` must be `[H, W]`, two positive integers (height, width), not `[{}]`",
                dotted(&size),
                given.join(", ")
            );
            let label = if spec.size.len() == 2 {
                "both must be at least 1"
            } else {
                "expected two values"
            };
            let help = Some("for example `size = [240, 320]`: 240 rows of 320 pixels".into());
            let d = loaded.diagnostic(&size, Target::Value, message, label);
            found.push(d.with_help(help));
        }
    }
    found
}
