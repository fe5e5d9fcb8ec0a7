//! chunkc: a compiler for robot-learning datasets.
//!
//! One checked-in TOML spec turns a raw demonstration dataset into one training-ready,
//! action-chunked, normalized dataset per target architecture, with the statistics and the
//! loader each needs, byte for byte reproducible.
//!
//! # The map
//!
//! **The rule**: a module imports only from the stages before it and from the leaves; the
//! command drivers sit on top. Stages talk through plain data types ([`spec::Spec`],
//! [`source::Episode`], [`audit::AuditReport`], [`plan::Plan`]), never through each other's
//! internals. `tests/layering.rs` checks every `crate::` path in `src/` against the order
//! below, and that this map names every module in it (the book's architecture page draws it).
//!
//! **Leaves**, usable by every stage:
//!
//! - [`error`]: the error type, its messages and exit codes.
//! - [`bytes`]: `f32` values viewed as the little-endian bytes of files.
//! - [`store`]: the row store, one channel's low-dim values at one rate, spilled to disk beyond a
//!   budget its caller decides (exec fills it, the sinks read it).
//! - [`timings`]: wall time per phase, printed when `CHUNKC_TIMINGS` is set.
//! - [`files`]: where chunkc may write (never into the source), and several files written as one.
//! - [`recycle`]: large byte buffers handed back after use (an episode's frames), so that the
//!   next episode's decode writes into memory already mapped.
//! - [`resize`]: camera frames resized as Diffusion Policy resizes them (cover the output keeping
//!   the aspect ratio with OpenCV's area or bilinear interpolation, then crop the centre).
//! - [`rotation`]: rotations in the representations datasets store (axis-angle, quaternions,
//!   Euler angles, matrices, 6D rows or columns) and the conversions between them.
//! - [`templates`]: the minijinja templates embedded in the binary, and the parts they include
//!   (`plan` bounds the generated files from them, `render` renders them).
//!
//! **The stages**, in order:
//!
//! 1. **Parse** ([`spec`]): TOML → [`spec::Spec`] → fully explicit [`spec::Profile`]s (presets
//!    expanded). Errors point at `file:line:col` with "did you mean". Also the per-format names
//!    every later stage shares ([`spec::OutputFormat::files`]).
//! 2. **Open** ([`source`]): an adapter per on-disk layout (Diffusion Policy zarr, ALOHA,
//!    robomimic/robosuite, LeRobot v2.1/v3.0 with their camera videos, [`source::video`],
//!    feature `video`) gives a [`source::Manifest`] (metadata only) and
//!    reads [`source::Episode`]s one at a time; [`source::mapping`] applies `[source.channels]`
//!    (rename, column slices, concatenation, kind) the same way for all of them.
//! 3. **Audit** ([`audit`]): inter-frame intervals per episode (timestamps only) → flags,
//!    verdicts and repairs ([`audit::AuditReport`]). [`audit::Audited`] is the source as the
//!    audit leaves it: exclusions gone, repaired lengths, each repair (cubic spline re-grid,
//!    Fourier or linear resampling) applied right after the episode is read.
//! 4. **Lock** ([`lock`]): `chunkc.lock`, what the last build recorded (spec hash, source
//!    fingerprint, every output's hash), read by the plan and written after a build.
//! 5. **Windows** ([`window`]): which rows every window reads; the invariants "never across an
//!    episode" and "the observation belongs to the chunk's first step" live there.
//!    Beside it, [`transform`]: a profile's action representations (`rotation`, `delta`,
//!    `relative_pose`) bound to the channels, and their math on one row.
//! 6. **Resolve** ([`plan`]): spec + audited manifest + audit + lock → [`plan::Plan`]: per
//!    profile the episodes and split, repairs and exclusions, rate conversion, window count,
//!    files, the state channel, fingerprint and whether it must run. Shared work (the source
//!    read, statistics per rate and channel) appears once.
//! 7. **Statistics** ([`stats`]): mergeable moments, exact percentiles, image histograms, the
//!    normalizers.
//! 8. **Write** ([`sink`]): one writer per output format (chunkc's HDF5, Zarr, LeRobot parquet,
//!    ACT episodes, robomimic), fed per-step arrays, frames and the window index, plus the
//!    documents beside them (`meta.json`, `stats.json`).
//! 9. **Render** ([`render`]): minijinja templates (embedded, overridable) for the generated
//!    loader (per profile: the parts of it the profile reads) and scripts, and the codebases'
//!    own statistics files.
//! 10. **Execute** ([`exec`]): one pass over the source into the row stores and sinks, the
//!     statistics per rate, each stale profile finished into a staging directory.
//!
//! **Beside the pipeline**: [`analyze`] suggests a chunk length K from the action channel's
//! autocorrelation; [`report`] draws the self-contained HTML pages of `audit` and `analyze`;
//! [`synth`] writes synthetic sources in every input layout (`chunkc synth`, for the benchmarks
//! and tests); [`fuzzing`] has the fuzz targets' bodies (one per input parser; see `fuzz/`);
//! [`init`] inspects a dataset and drafts its first spec (`chunkc init`, `chunkc inspect`).
//!
//! **On top**: [`commands`], the drivers of `check`, `plan`, `audit`, `analyze`, `build`,
//! `merge` and `init` (re-planning after an exclusion, the sharded build, the commit, the lock update). `main.rs` is the command line
//! only: it parses arguments, sizes the thread pool, calls a driver and prints its result.
//!
//! # Threads
//!
//! All parallel work runs on rayon's global pool, sized once by `main.rs` (`-j`, else
//! `RAYON_NUM_THREADS`, else the cores); results are always gathered in a fixed order, so the
//! output bytes do not depend on the thread count. Where, and why:
//!
//! - [`exec`]: episodes of a batch decoded and converted side by side, the row stores filled
//!   side by side, rates and profiles finished side by side; a few plain threads fsync outputs
//!   while they are hashed (they wait on the disk, not the CPU). A Zarr store's files and a
//!   LeRobot export's parquet files are hashed by their writers as they write them.
//! - [`source`]: storage chunks decoded in parallel (zarr, ALOHA's per-episode headers), the
//!   cameras of a LeRobot episode decoded side by side (one decoder thread per video file), and
//!   the source fingerprint hashed beside the pass (zarr chunks as they are read; other files
//!   by one low-priority thread of its own).
//! - [`audit`]: the camera videos' packet times demuxed for several episodes at once.
//! - [`stats`]: the percentile passes, one column per task.
//! - [`sink`]: frames compressed and normalized blocks prepared in parallel, while the previous
//!   block is written (`rayon::join`).
//! - [`synth`]: synthetic episodes generated in parallel.
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
pub mod commands;
pub mod error;
pub mod exec;
pub mod files;
pub mod fuzzing;
pub mod init;
pub mod lock;
pub mod plan;
pub mod recycle;
pub mod render;
pub mod report;
pub mod resize;
pub mod rotation;
pub mod sink;
pub mod source;
pub mod spec;
pub mod stats;
pub mod store;
pub mod synth;
pub mod templates;
pub mod timings;
pub mod transform;
pub mod window;

pub use error::{Error, Result};
