//! `chunkc check`: the spec parses and validates, the source opens and audits, the plan
//! resolves; nothing is written.

use crate::error::Result;
use crate::plan::Plan;
use crate::spec::LoadedSpec;

/// The plan `build` would follow (its source dropped); an error is what `check` reports.
pub fn check(spec: &LoadedSpec) -> Result<Plan> {
    super::plan(spec).map(|(_, plan)| plan)
}
