//! Stage 4, resolve: spec + source manifest + lock → [`Plan`].
//!
//! The plan is data: serializable, versioned, sorted. It says, for every profile, which episodes
//! it uses and how they split, the rate conversion, the number of windows, the files it writes
//! with estimated sizes, a fingerprint, and whether it must run (and why). Work shared between
//! profiles appears once: the source read, and the statistics of each (rate, channel) pair.
//!
//! - `types`: the plan's serializable types.
//! - `resolve`: building the plan from the spec, the manifest and the lock.
//! - `cameras`: the cameras a profile resizes, checked against the source's frames.
//! - `sampling`: windows, segments or hierarchical chunks, checked against the channels.
//! - `estimate`: the files a profile writes, with an upper bound or an estimate of their sizes.
//! - `freshness`: whether a profile is up to date, and the typed reason when it is not.
//! - `groot`: a `groot` profile's GR00T modality (state, action and video keys, relative
//!   actions) per dataset, checked against the channels' widths.
//! - `split`: the deterministic train/validation split.
//! - `mixture`: a training mixture's split (per source) and its sources' sampling weights.
//! - `export`: where each channel's array lives in the profile's container (native exports
//!   name them as their codebase's configuration does).
//! - `shards`: which episodes each shard of a sharded build reads, and the plan's identity.
//! - `transforms`: a profile's action representations checked against the channels and bound
//!   to them (`abs_action` expanded).
//! - `text`: the human-readable rendering of `chunkc plan`.

mod abs_action;
mod cameras;
pub mod estimate;
pub mod export;
pub mod freshness;
pub mod groot;
pub mod mixture;
mod resolve;
mod sampling;
pub mod shards;
pub mod split;
mod text;
mod transform_errors;
mod transform_fit;
mod transforms;
mod types;

pub use crate::audit::conversion::{conversion, Conversion};
pub use cameras::CameraResize;

/// Orders rates from the fastest: the source rate first, as decimation factors 1, 2, … did.
fn rate_order(fps: f64) -> usize {
    usize::MAX - (fps * 1e6).round() as usize
}
pub use freshness::{DirtyReason, FileChange, Status};
pub use resolve::{apply_audit, resolve};
pub use split::Split;
pub use text::render_text;
pub use types::*;

pub const PLAN_VERSION: u32 = 1;
pub const TOOL_VERSION: &str = env!("CARGO_PKG_VERSION");

/// Files every profile writes, relative to its directory.
pub const META_FILE: &str = "meta.json";
pub const STATS_FILE: &str = "stats.json";
pub const LOADER_FILE: &str = "loader.py";
