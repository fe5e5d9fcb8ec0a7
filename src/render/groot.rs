//! `groot_config.py`: GR00T N1.7's modality config of each `groot` training dataset (the
//! profile folder, or a mixture source's `sources/<name>/`), the file its fine-tuning script
//! takes as `--modality-config-path`: the modality keys of the dataset's `meta/modality.json`,
//! the action horizon, and which actions GR00T makes relative.

use minijinja::context;

use super::Renderer;
use crate::error::Result;
use crate::plan::groot::TASK_ANNOTATION;
use crate::plan::{ProfilePlan, TOOL_VERSION};

/// The file's name, in each training dataset's folder.
pub const CONFIG_FILE: &str = "groot_config.py";

/// (path in the profile folder, text) of each training dataset's config; none for a profile
/// that is not a `groot` one.
pub fn configs(
    r: &Renderer,
    p: &ProfilePlan,
    sources: &[crate::source::SourcePart],
) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for (s, m) in p.groot.iter().enumerate() {
        let source = (p.groot.len() > 1).then(|| sources[s].name.as_str());
        let action: Vec<_> = (m.action.iter())
            .map(|a| context! { name => a.name, relative => m.relative_actions.contains(&a.name) })
            .collect();
        let text = r.render(
            CONFIG_FILE,
            context! {
                version => TOOL_VERSION,
                source,
                horizon => p.window().chunk,
                video => m.video.iter().map(|(k, _)| k).collect::<Vec<_>>(),
                state => m.state.iter().map(|s| &s.name).collect::<Vec<_>>(),
                action,
                relative => m.relative_actions,
                annotation => TASK_ANNOTATION,
            },
        )?;
        let path = match source {
            Some(name) => format!("sources/{name}/{CONFIG_FILE}"),
            None => CONFIG_FILE.to_string(),
        };
        out.push((path, text));
    }
    Ok(out)
}
