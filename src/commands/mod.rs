//! The command drivers, on top of every stage: each `chunkc` command that does more than one
//! stage's work is one function here, which `main.rs` (the command line only) calls and whose
//! result it prints. The drivers sequence the stages (open, audit, resolve, execute, render)
//! and own what belongs to no single stage: re-planning after an exclusion, committing the
//! staging directory, updating `chunkc.lock`.
//!
//! - `audit`: open the source and audit it; `chunkc audit` writes the report.
//! - `plan`: the audited source and the plan against the lock (`chunkc plan`).
//! - `measure`: what `plan` measures of lossily stored frames for its size estimates.
//! - `check`: the plan, for `chunkc check`'s one line.
//! - `analyze`: the chunk-length analysis and its report.
//! - `build`: the stale profiles built, committed and locked.
//! - `card`: each built profile's dataset card, once the build's audit is final.
//! - `shard`: a sharded build: one shard's partial (`build --shard`), and the merge of all.
//! - `init`: a dataset inspected and a first spec written from it, once it checks.

mod analyze;
mod audit;
mod build;
mod card;
mod check;
mod init;
mod measure;
mod mixture;
mod plan;
mod shard;

pub use analyze::analyze;
pub use audit::{audit, audit_report, Audit};
pub use build::{build, BuildOptions, BuildReport};
pub use check::check;
pub use init::init;
pub use plan::plan;
pub use shard::{build_shard, merge};
