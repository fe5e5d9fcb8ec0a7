//! chunkc: a compiler for robot-learning datasets.
//!
//! One checked-in TOML spec turns a raw demonstration dataset into one training-ready,
//! action-chunked, normalized dataset per target architecture, with the statistics and the
//! loader each needs, byte for byte reproducible.
//!
//! # The map
//!
//! The stages run in this order; each owns one module and they talk through plain data types.
//!
//! 1. **Parse** ([`spec`]): TOML → [`spec::Spec`] → fully explicit [`spec::Profile`]s (presets
//!    expanded). Errors point at `file:line:col` with "did you mean".
//! 2. **Open** ([`source`]): an adapter per on-disk layout (Diffusion Policy zarr, ALOHA,
//!    robomimic/robosuite, LeRobot v2.1/v3.0) gives a [`source::Manifest`] (metadata only) and
//!    reads [`source::Episode`]s one at a time; [`source::mapping`] applies `[source.channels]`
//!    (rename, column slices, concatenation, kind) the same way for all of them.
//! 3. **Audit** ([`audit`]): inter-frame intervals per episode → verdicts and repairs
//!    ([`audit::AuditReport`]).
//! 4. **Resolve** ([`plan`]): spec + manifest + [`lock`] → [`plan::Plan`]: per profile the
//!    episodes and split, rate conversion, window count, files, fingerprint and whether it must
//!    run. Shared work (the source read, statistics per rate and channel) appears once.
//! 5. **Execute** ([`exec`]): the only module with threads. Reads the source once, decimates per
//!    rate, computes [`stats`], normalizes, and writes through [`sink`] into a staging directory
//!    renamed into place on success; then writes `chunkc.lock`.
//! 6. **Render** ([`render`]): minijinja templates (embedded) for the generated Python loader.
//!
//! Supporting pieces: [`chunk`] decides which rows every window reads (the invariants "never
//! across an episode" and "the observation belongs to the chunk's first step" live there);
//! [`error`] holds the error type and exit codes;
//! [`fuzzing`] has the fuzz targets' bodies (one per input parser; see `fuzz/`).

pub mod audit;
pub mod chunk;
pub mod error;
pub mod exec;
pub mod fuzzing;
pub mod lock;
pub mod plan;
pub mod render;
pub mod sink;
pub mod source;
pub mod spec;
pub mod stats;

pub use error::{Error, Result};
