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
//! - `codebase`: statistics files in each target codebase's own format.
//! - `pickle`: the minimal pickle writer behind ACT's `dataset_stats.pkl`.

pub mod codebase;
pub mod pickle;

use std::collections::BTreeMap;
use std::path::Path;

use minijinja::{context, Environment, Value};

use crate::error::{Error, IoContext, Result};
use crate::plan::{Plan, ProfilePlan, TOOL_VERSION};

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

/// What the generated files of one profile are rendered from.
pub struct ProfileContext<'a> {
    pub plan: &'a Plan,
    pub profile: &'a ProfilePlan,
    pub spec_file: &'a str,
    pub output_hint: &'a str,
    pub data_file: &'a str,
    pub num_samples: [usize; 2],
    /// (file name, what it is) of the codebase statistics files written.
    pub stats_files: &'a [(String, String)],
}

/// `loader.py`, `policy.py`, `validate.py`, `smoke_train.py`, `rollout.py` when the profile names
/// an `env` (the same for every profile) and the dataset
/// card `README.md`.
// Long function: one entry per generated file, rendered in the order the card lists them.
pub fn profile_files(r: &Renderer, c: &ProfileContext) -> Result<Vec<(&'static str, String)>> {
    let p = c.profile;
    let v = &p.values;
    let values: Vec<Value> = p
        .resolved_values()
        .into_iter()
        .map(|r| context! { key => r.key, value => r.value, origin => r.origin })
        .collect();
    let channels: Vec<Value> = p
        .channels
        .iter()
        .map(|ch| {
            context! {
                name => ch.name,
                kind => format!("{:?}", ch.kind).to_lowercase(),
                shape => format!("{:?}", ch.shape),
                normalize => ch.normalize.name(),
            }
        })
        .collect();
    let stats_files: Vec<Value> = c
        .stats_files
        .iter()
        .map(|(name, what)| context! { name, what })
        .collect();
    let stats_hints: Vec<&str> = v
        .stats_formats
        .iter()
        .map(|f| match f {
            crate::spec::StatsFormat::Act => {
                "ACT: copy `dataset_stats.pkl` into the checkpoint directory; `imitate_episodes.py` reads it"
            }
            crate::spec::StatsFormat::DiffusionPolicy => {
                "Diffusion Policy: `dp_normalizer.load_state_dict()` gives the policy's LinearNormalizer state"
            }
            crate::spec::StatsFormat::Lerobot => {
                "LeRobot: `lerobot_stats.json` has the layout of `meta/stats.json`"
            }
            crate::spec::StatsFormat::Openpi => {
                "openpi: `norm_stats.json` goes in the assets directory of the training config"
            }
            crate::spec::StatsFormat::Robomimic => {
                "robomimic: `robomimic_stats.json` holds `obs_normalization_stats` (v0.5 and v0.4 forms)"
            }
        })
        .collect();
    // The profile's tasks (RLDS language instructions), each with its number of episodes.
    let mut task_counts: BTreeMap<&str, usize> = BTreeMap::new();
    for e in &p.episodes {
        if let Some(t) = c.plan.source.tasks.get(&e.id) {
            *task_counts.entry(t.as_str()).or_default() += 1;
        }
    }
    let tasks: Vec<Value> = task_counts
        .iter()
        .map(|(task, episodes)| context! { task, episodes })
        .collect();
    let card = context! {
        profile => p.name,
        tasks,
        version => TOOL_VERSION,
        spec_file => c.spec_file,
        spec_hash => c.plan.spec_hash,
        source => c.plan.source,
        values,
        rate => p.rate,
        sampling => p.sampling.name(),
        train_episodes => p.episodes.iter().filter(|e| e.split == "train").count(),
        val_episodes => p.episodes.iter().filter(|e| e.split == "val").count(),
        num_samples => context! { train => c.num_samples[0], val => c.num_samples[1] },
        warnings => p.warnings,
        channels,
        audit => "no timing audit was run for this build.",
        data_file => c.data_file,
        stats_files,
        stats_hints,
        output_hint => c.output_hint,
        chunk => p.window().chunk,
    };
    let mut files = vec![
        ("loader.py", shared_script(r, "loader.py")?),
        ("policy.py", shared_script(r, "policy.py")?),
        ("validate.py", shared_script(r, "validate.py")?),
        ("smoke_train.py", shared_script(r, "smoke_train.py")?),
    ];
    if v.env.is_some() {
        files.push(("rollout.py", shared_script(r, "rollout.py")?));
    }
    files.push(("README.md", r.render("README.md", card)?));
    Ok(files)
}
