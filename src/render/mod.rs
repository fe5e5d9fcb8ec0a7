//! Stage 6, render: generated files from minijinja templates embedded in the binary, each
//! overridable by a file of the same name (plus `.j2`) in the spec's `[output] templates`
//! directory.
//!
//! The generated scripts (`loader.py`, `policy.py`, `validate.py`, `smoke_train.py`,
//! `rollout.py` for profiles naming a simulator, `dp_normalizer.py`) are
//! one static library per chunkc version: identical bytes in every profile directory, reading
//! the profile from `meta.json` at run time ([`SHARED_SCRIPTS`]). What differs per profile is in
//! `meta.json`, the statistics files and the dataset card.
//!
//! - `card`: the dataset card, written once the build's audit has judged.
//! - `codebase`: statistics files in each target codebase's own format.
//! - `pickle`: the minimal pickle writer behind ACT's `dataset_stats.pkl`.
//! - `groot`: a `groot` profile's `groot_config.py` (GR00T's modality config of each training
//!   dataset), from the plan's modality.

pub mod card;
pub mod codebase;
pub mod groot;
pub mod pickle;

use std::path::Path;

use minijinja::{context, Environment, Value};

use crate::error::{Error, IoContext, Result};
use crate::plan::{ProfilePlan, TOOL_VERSION};

/// Every embedded template, by the name of the file it renders.
pub const TEMPLATES: &[(&str, &str)] = &[
    ("loader.py", include_str!("../../templates/loader.py.j2")),
    (
        "validate.py",
        include_str!("../../templates/validate.py.j2"),
    ),
    (
        "smoke_train.py",
        include_str!("../../templates/smoke_train.py.j2"),
    ),
    ("policy.py", include_str!("../../templates/policy.py.j2")),
    ("rollout.py", include_str!("../../templates/rollout.py.j2")),
    ("README.md", include_str!("../../templates/README.md.j2")),
    (
        "dp_normalizer.py",
        include_str!("../../templates/dp_normalizer.py.j2"),
    ),
    (
        "groot_config.py",
        include_str!("../../templates/groot_config.py.j2"),
    ),
];

/// The template environment: the embedded templates, with the user's overrides applied.
pub struct Renderer {
    env: Environment<'static>,
}

impl Renderer {
    /// `overrides`: a directory holding `<file>.j2` for any generated file to replace.
    pub fn new(overrides: Option<&Path>) -> Result<Self> {
        let mut env = Environment::new();
        env.set_keep_trailing_newline(true);
        for (name, source) in TEMPLATES {
            env.add_template(name, source)
                .expect("embedded templates parse");
        }
        if let Some(dir) = overrides {
            let known: Vec<&str> = TEMPLATES.iter().map(|(n, _)| *n).collect();
            for entry in std::fs::read_dir(dir).at("read templates directory", dir)? {
                let path = entry.at("read templates directory", dir)?.path();
                let file = path
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
                    .to_string();
                let Some(name) = file.strip_suffix(".j2").filter(|n| known.contains(n)) else {
                    return Err(Error::Spec(format!(
                        "{}: not a chunkc template; overridable templates are {}",
                        path.display(),
                        known
                            .iter()
                            .map(|n| format!("{n}.j2"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )));
                };
                let source = std::fs::read_to_string(&path).at("read template", &path)?;
                env.add_template_owned(name.to_string(), source)
                    .map_err(|e| Error::Spec(format!("{}: {e}", path.display())))?;
            }
        }
        Ok(Renderer { env })
    }

    pub fn render(&self, name: &str, ctx: Value) -> Result<String> {
        self.env
            .get_template(name)
            .and_then(|t| t.render(ctx))
            .map_err(|e| Error::output(format!("rendering {name}: {e:#}")))
    }
}

/// The generated scripts that are the same file for every profile of a chunkc version: they
/// read what they need of the profile from its `meta.json` at run time, so their templates see
/// only `version`.
pub const SHARED_SCRIPTS: &[&str] = &[
    "loader.py",
    "validate.py",
    "smoke_train.py",
    "policy.py",
    "rollout.py",
    "dp_normalizer.py",
];

/// One of [`SHARED_SCRIPTS`], as `r` renders it.
pub fn shared_script(r: &Renderer, name: &str) -> Result<String> {
    debug_assert!(
        SHARED_SCRIPTS.contains(&name),
        "{name} is not a shared script"
    );
    r.render(name, context! { version => TOOL_VERSION })
}

/// `loader.py`, `policy.py`, `validate.py`, `smoke_train.py`, and `rollout.py` when the profile
/// names an `env` (the same for every profile). The dataset card comes later ([`card::card`]):
/// it says what the build's audit judged.
pub fn profile_files(r: &Renderer, profile: &ProfilePlan) -> Result<Vec<(&'static str, String)>> {
    let mut files = vec![
        ("loader.py", shared_script(r, "loader.py")?),
        ("policy.py", shared_script(r, "policy.py")?),
        ("validate.py", shared_script(r, "validate.py")?),
        ("smoke_train.py", shared_script(r, "smoke_train.py")?),
    ];
    if profile.values.env.is_some() {
        files.push(("rollout.py", shared_script(r, "rollout.py")?));
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `plan` bounds the scripts' sizes from the same templates.
    #[test]
    fn the_plan_bounds_every_shared_script() {
        let r = Renderer::new(None).unwrap();
        for name in SHARED_SCRIPTS {
            let (_, template) = crate::plan::estimate::SCRIPTS
                .iter()
                .find(|(n, _)| n == name)
                .unwrap_or_else(|| panic!("plan::estimate::SCRIPTS lacks {name}"));
            let text = shared_script(&r, name).unwrap();
            assert!(
                text.len() as u64 <= crate::plan::estimate::script_bound(template),
                "{name}"
            );
            let embedded = TEMPLATES.iter().find(|(n, _)| n == name).unwrap().1;
            assert_eq!(*template, embedded, "{name}");
        }
    }
}
