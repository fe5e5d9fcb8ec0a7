//! The findings the judgement gathers, per episode, before they go into the report.

use super::Finding;
use crate::audit::report::Flag;
use crate::spec::DoctorAction;

/// The findings being gathered, per episode (in the features' order).
pub(super) struct Found(pub(super) Vec<Vec<Finding>>);

impl Found {
    pub(super) fn add(
        &mut self,
        e: usize,
        flag: Flag,
        action: DoctorAction,
        detail: String,
        ev: &[(&str, f64)],
    ) {
        self.0[e].push(Finding {
            flag,
            action,
            detail,
            evidence: ev.iter().map(|(k, v)| (k.to_string(), *v)).collect(),
        });
    }
}
