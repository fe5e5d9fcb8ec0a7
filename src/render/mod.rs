//! Stage 6, render: generated text files from minijinja templates embedded in the binary.

use minijinja::{context, Environment};

use crate::error::{Error, Result};
use crate::plan::{ProfilePlan, TOOL_VERSION};

const LOADER: &str = include_str!("../../templates/loader.py.j2");

fn env() -> Environment<'static> {
    let mut env = Environment::new();
    env.set_keep_trailing_newline(true);
    env.add_template("loader.py", LOADER)
        .expect("embedded loader template parses");
    env
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
