//! Stage 6, render: generated files from minijinja templates embedded in the binary
//! ([`crate::templates`]), each overridable by a file of the same name (plus `.j2`) in the
//! spec's `[output] templates` directory, and so is each part a template includes
//! (`loader/<part>.py.j2`, `validate/<part>.py.j2`).
//!
//! `loader.py` and `validate.py` are generated per profile, from the parts that the profile
//! reads ([`parts::Parts`]), so that each file holds the code of its dataset and no other. The
//! other scripts (`policy.py`, `smoke_train.py`, `rollout.py` for profiles naming a simulator,
//! `dp_normalizer.py`) are one static library per chunkc version: identical bytes in every
//! profile directory, reading the profile from `meta.json` at run time ([`SHARED_SCRIPTS`]).
//! What else differs per profile is in `meta.json`, the statistics files and the dataset card.
//!
//! - `card`: the dataset card, written once the build's audit has judged.
//! - `codebase`: statistics files in each target codebase's own format.
//! - `parts`: which parts of the loader (and of `validate.py`) a profile's files hold.
//! - `pickle`: the minimal pickle writer behind ACT's `dataset_stats.pkl`.
//! - `groot`: a `groot` profile's `groot_config.py` (GR00T's modality config of each training
//!   dataset), from the plan's modality.

pub mod card;
pub mod codebase;
pub mod groot;
pub mod parts;
pub mod pickle;

use std::path::Path;

use minijinja::{context, Environment, Value};

use crate::error::{Error, IoContext, Result};
use crate::plan::{Plan, ProfilePlan, TOOL_VERSION};
use crate::templates::{FILES, PARTS};
use parts::Parts;

/// The template environments: the embedded templates, with the user's overrides applied.
pub struct Renderer {
    /// The Python scripts and their parts: a block tag alone on its line leaves no trace of the
    /// line (`trim_blocks`, `lstrip_blocks`), so that templates read as the code they write.
    code: Environment<'static>,
    /// The dataset card (Markdown), whose tags sit inside its lines.
    text: Environment<'static>,
}

/// Whether template `name` renders Python (see [`Renderer`]).
fn is_code(name: &str) -> bool {
    name.ends_with(".py")
}

impl Renderer {
    /// `overrides`: a directory holding `<file>.j2` for any generated file to replace, and
    /// `<file stem>/<part>.j2` for any part of one (`loader/dataset.py.j2`).
    pub fn new(overrides: Option<&Path>) -> Result<Self> {
        let mut code = Environment::new();
        code.set_keep_trailing_newline(true);
        code.set_trim_blocks(true);
        code.set_lstrip_blocks(true);
        let mut text = Environment::new();
        text.set_keep_trailing_newline(true);
        let mut r = Renderer { code, text };
        for (name, source) in FILES.iter().chain(PARTS) {
            r.env_mut(name)
                .add_template(name, source)
                .expect("embedded templates parse");
        }
        if let Some(dir) = overrides {
            for (name, path) in override_files(dir)? {
                let source = std::fs::read_to_string(&path).at("read template", &path)?;
                r.env_mut(&name)
                    .add_template_owned(name.clone(), source)
                    .map_err(|e| Error::Spec(format!("{}: {e}", path.display())))?;
            }
        }
        Ok(r)
    }

    fn env_mut(&mut self, name: &str) -> &mut Environment<'static> {
        if is_code(name) {
            &mut self.code
        } else {
            &mut self.text
        }
    }

    pub fn render(&self, name: &str, ctx: Value) -> Result<String> {
        let env = if is_code(name) {
            &self.code
        } else {
            &self.text
        };
        env.get_template(name)
            .and_then(|t| t.render(ctx))
            .map_err(|e| Error::output(format!("rendering {name}: {e:#}")))
    }
}

/// `(template name, path)` of each file in the overrides directory `dir` (its subdirectories
/// hold parts); any other file is an error, so that a typo does not silently fall back to the
/// built-in template.
fn override_files(dir: &Path) -> Result<Vec<(String, std::path::PathBuf)>> {
    let known: Vec<&str> = FILES.iter().chain(PARTS).map(|(n, _)| *n).collect();
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(at) = stack.pop() {
        for entry in std::fs::read_dir(&at).at("read templates directory", &at)? {
            let path = entry.at("read templates directory", &at)?.path();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            let rel = path
                .strip_prefix(dir)
                .unwrap_or(&path)
                .to_string_lossy()
                .replace('\\', "/");
            let Some(name) = rel.strip_suffix(".j2").filter(|n| known.contains(n)) else {
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
            out.push((name.to_string(), path));
        }
    }
    out.sort();
    Ok(out)
}

/// The generated scripts that are the same file for every profile of a chunkc version: they
/// read what they need of the profile from its `meta.json` at run time, so their templates see
/// only `version`.
pub const SHARED_SCRIPTS: &[&str] = &[
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

/// The scripts generated per profile, from the parts it reads ([`Parts`]).
pub const PROFILE_SCRIPTS: &[&str] = &["loader.py", "validate.py"];

/// `loader.py` of profile `p`: the parts of chunkc's loader that it reads.
pub fn loader(r: &Renderer, plan: &Plan, p: &ProfilePlan) -> Result<String> {
    loader_with(r, Parts::of(plan, p))
}

/// `loader.py` with `parts`.
pub fn loader_with(r: &Renderer, parts: Parts) -> Result<String> {
    script_with(r, "loader.py", parts)
}

/// One of [`PROFILE_SCRIPTS`] with `parts`. Its templates also see `every` ([`Parts::every`]),
/// which a template override may render instead.
pub fn script_with(r: &Renderer, name: &str, parts: Parts) -> Result<String> {
    debug_assert!(
        PROFILE_SCRIPTS.contains(&name),
        "{name} is not generated per profile"
    );
    r.render(
        name,
        context! {
            version => TOOL_VERSION,
            parts => parts.context(),
            every => Parts::every().context(),
        },
    )
}

/// `loader.py` and `validate.py` (from the parts the profile reads), `policy.py`,
/// `smoke_train.py`, and `rollout.py` when the profile names an `env` (the same for every
/// profile). The dataset card comes later ([`card::card`]): it says what the build's audit
/// judged.
pub fn profile_files(
    r: &Renderer,
    plan: &Plan,
    profile: &ProfilePlan,
) -> Result<Vec<(&'static str, String)>> {
    let parts = Parts::of(plan, profile);
    let mut files = vec![
        ("loader.py", script_with(r, "loader.py", parts)?),
        ("policy.py", shared_script(r, "policy.py")?),
        ("validate.py", script_with(r, "validate.py", parts)?),
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
    use crate::plan::estimate::script_bound;

    /// `plan` bounds the shared scripts' sizes from their templates.
    #[test]
    fn the_plan_bounds_every_shared_script() {
        let r = Renderer::new(None).unwrap();
        for name in SHARED_SCRIPTS {
            let template = crate::templates::file(name).unwrap();
            let text = shared_script(&r, name).unwrap();
            assert!(text.len() as u64 <= script_bound(template, []), "{name}");
            assert!(crate::plan::estimate::SCRIPTS.contains(name), "{name}");
        }
    }

    /// Loaders and validate.py with one part, all but one, none and every part: each within
    /// the plan's bound, and valid template output (no tag left, no line of spaces).
    #[test]
    fn the_plan_bounds_every_profile_script() {
        let r = Renderer::new(None).unwrap();
        for name in PROFILE_SCRIPTS {
            let template = crate::templates::file(name).unwrap();
            let bound = script_bound(template, crate::templates::parts_of(name).map(|(_, t)| *t));
            assert!(crate::plan::estimate::SCRIPTS.contains(name), "{name}");
            for parts in parts::tests::combinations() {
                let text = script_with(&r, name, parts).unwrap();
                assert!(text.len() as u64 <= bound, "{name} {parts:?}");
                assert!(!text.contains("{%") && !text.contains("{{") && !text.contains("{#"));
                assert!(
                    !text.lines().any(|l| !l.is_empty() && l.trim().is_empty()),
                    "{name} {parts:?}: a line of spaces"
                );
            }
        }
    }

    /// A low-dim HDF5 profile's loader (Push-T's `act` without its camera: no camera, transform,
    /// mixture or segment) holds its own code and little else: at most 400 lines.
    #[test]
    fn a_low_dim_loader_is_short() {
        let r = Renderer::new(None).unwrap();
        let parts = Parts {
            hdf5: true,
            ..Parts::default()
        };
        let lines = loader_with(&r, parts).unwrap().lines().count();
        assert!(lines <= 400, "{lines} lines");
    }
}
