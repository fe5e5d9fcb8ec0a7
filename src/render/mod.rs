//! Stage 6, render: generated files from minijinja templates embedded in the binary.
//!
//! - `codebase`: statistics files in each target codebase's own format.
//! - `pickle`: the minimal pickle writer behind ACT's `dataset_stats.pkl`.

pub mod codebase;
pub mod pickle;

use minijinja::{context, Environment};

use crate::error::{Error, Result};
use crate::plan::{ProfilePlan, TOOL_VERSION};

/// Every embedded template, by the name of the file it renders.
const TEMPLATES: &[(&str, &str)] = &[
    ("loader.py", include_str!("../../templates/loader.py.j2")),
    (
        "dp_normalizer.py",
        include_str!("../../templates/dp_normalizer.py.j2"),
    ),
];

fn env() -> Environment<'static> {
    let mut env = Environment::new();
    env.set_keep_trailing_newline(true);
    for (name, source) in TEMPLATES {
        env.add_template(name, source)
            .expect("embedded templates parse");
    }
    env
}

/// Renders an embedded template that takes no user input (cannot fail at run time).
pub(crate) fn render_template(name: &str, ctx: minijinja::Value) -> String {
    env()
        .get_template(name)
        .and_then(|t| t.render(ctx))
        .unwrap_or_else(|e| panic!("embedded template {name} failed to render: {e}"))
}

/// `loader.py` for one profile.
pub fn loader(profile: &ProfilePlan, output_hint: &str) -> Result<String> {
    let channels: Vec<&str> = profile.channels.iter().map(|c| c.name.as_str()).collect();
    let channels_py = format!(
        "[{}]",
        channels
            .iter()
            .map(|c| format!("{c:?}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    env()
        .get_template("loader.py")
        .and_then(|t| {
            t.render(context! {
                profile => profile.name,
                version => TOOL_VERSION,
                alignment => profile.values.alignment,
                output_hint => output_hint,
                channels => channels_py,
            })
        })
        .map_err(|e| Error::Internal(format!("rendering loader.py: {e}")))
}
