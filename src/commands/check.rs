//! `chunkc check`: the spec parses and validates, the source opens and audits, the plan
//! resolves; nothing is written. A spec that is valid but trains a policy on nothing (no
//! observation channel) gets a warning.

use crate::error::Result;
use crate::plan::Plan;
use crate::spec::{self, LoadedSpec};

/// The plan `build` would follow (its source dropped); an error is what `check` reports, a
/// warning goes to stderr.
pub fn check(spec: &LoadedSpec) -> Result<Plan> {
    let plan = super::plan(spec).map(|(_, plan)| plan)?;
    for warning in spec::missing_observations(spec) {
        eprintln!("warning: {warning}");
    }
    Ok(plan)
}
