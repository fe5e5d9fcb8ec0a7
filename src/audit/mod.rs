//! Stage 3, audit: inter-frame intervals per episode → a verdict (ok, interpolate dropped frames,
//! resample, exclude) under the thresholds in `[audit]`.
//!
//! - `report`: the result as data ([`AuditReport`]), written as `audit/audit.json`.

pub mod report;

pub use report::{AuditReport, EpisodeAudit, Flag, Histogram, RepairExample, Thresholds, Verdict};
