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
//! 3. **Audit** ([`audit`]): inter-frame intervals per episode (timestamps only) → flags,
//!    verdicts and repairs ([`audit::AuditReport`], `chunkc audit`). [`audit::Audited`] is the
//!    source as the audit leaves it: exclusions gone, repaired lengths, each repair (cubic spline
//!    re-grid, Fourier or linear resampling) applied right after the episode is read.
//! 4. **Resolve** ([`plan`]): spec + audited manifest + audit + [`lock`] → [`plan::Plan`]: per
//!    profile the episodes and split, repairs and exclusions, rate conversion (decimation or
//!    resampling), window count, files, fingerprint and whether it must run. Shared work (the
//!    source read, statistics per rate and channel) appears once.
//! 5. **Execute** ([`exec`]): the only module with threads. Reads the source once, converts per
//!    rate, keeps low-dim values in an [`exec::LowdimStore`] (spilled to the staging directory
//!    beyond a memory budget), computes [`stats`], normalizes, and writes through [`sink`] into a
//!    staging directory renamed into place on success; then writes `chunkc.lock`.
//! 6. **Render** ([`render`]): minijinja templates (embedded) for the generated Python loader;
//!    [`report`]: the self-contained HTML reports (inline SVG charts) of `audit` and `analyze`.
//!
//! Beside the pipeline, [`analyze`] (`chunkc analyze`) reads the action channel and suggests a
//! chunk length K from its autocorrelation, checking every profile's K against it.
//!
//! Supporting pieces: [`window`] decides which rows every window reads (the invariants "never
//! across an episode" and "the observation belongs to the chunk's first step" live there);
//! [`error`] holds the error type and exit codes; [`bytes`] views `f32` values as the
//! little-endian bytes of files; [`synth`] writes synthetic sources in every
//! input layout (`chunkc synth`, for the benchmarks and tests); [`fuzzing`] has the fuzz targets'
//! bodies (one per input parser; see `fuzz/`).
//!
//! # Words
//!
//! - **chunk**: the action chunk, the K steps of actions a sample holds (`profiles.*.chunk`, the
//!   `/chunks` datasets of the materialized and virtual HDF5 layouts); nothing else.
//! - **window**: the rows one sample reads, actions and observations ([`window`]).
//! - **block**: one storage chunk of a source file, an HDF5 or zarr chunk or a parquet row group
//!   (`source::block_map`, `source::block_cache`). Spec keys and book text about zarr
//!   "chunking" keep the formats' own word.

pub mod analyze;
pub mod audit;
pub mod bytes;
pub mod error;
pub mod exec;
pub mod fuzzing;
pub mod lock;
pub mod plan;
pub mod render;
pub mod report;
pub mod sink;
pub mod source;
pub mod spec;
pub mod stats;
pub mod synth;
pub mod window;

pub use error::{Error, Result};
