// Long file: the command line, every command's clap definition and its printout; each does its work in the library.
//! The `chunkc` command line. Everything it does is a call into the library.

use std::path::{Component, Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

use chunkc::commands::{self, BuildOptions};
use chunkc::spec::{self, LoadedSpec, MemorySize, SourceFormat};
use chunkc::{analyze, init, plan, synth, Error};

#[derive(Parser)]
#[command(
    name = "chunkc",
    version,
    about = "Compile robot demonstration datasets into training-ready action chunks"
)]
struct Cli {
    /// Worker threads (default: RAYON_NUM_THREADS, else the number of cores).
    #[arg(long, short = 'j', global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Parse and validate a spec, and check that its source opens.
    Check { spec: PathBuf },
    /// Show what `build` would do, without writing anything.
    Plan {
        spec: PathBuf,
        #[arg(long, value_enum, default_value_t = PlanFormat::Text)]
        format: PlanFormat,
        /// Also show how N shards would split the episodes, with each shard's steps, estimated
        /// bytes and read time.
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        shards: Option<u64>,
    },
    /// Build every profile of a spec that is not up to date.
    Build {
        spec: PathBuf,
        /// Fail (exit 5) instead of building if any output is out of date.
        #[arg(long)]
        locked: bool,
        /// No progress bars.
        #[arg(long, short)]
        quiet: bool,
        /// Build only shard I of N (from 0; e.g. `--shard $SLURM_ARRAY_TASK_ID/16`): its
        /// episodes are processed into a partial in `--partials`, for `chunkc merge`. Nothing is
        /// written to the output directory.
        #[arg(long, requires = "partials", conflicts_with = "locked")]
        shard: Option<plan::shards::Shard>,
        /// Where shards write their partials and `merge` reads them (shared by every worker).
        #[arg(long, requires = "shard")]
        partials: Option<PathBuf>,
        /// The memory the build may keep values in before it writes them, with a unit
        /// (`2GiB`); over `[build] memory`. Default: a quarter of the available memory.
        #[arg(long)]
        memory: Option<MemorySize>,
    },
    /// Build every profile from the partials of all N shards (`build --shard I/N`): the same
    /// bytes as `chunkc build`. Checks that every shard is there and from this plan first.
    Merge {
        spec: PathBuf,
        #[arg(long)]
        partials: PathBuf,
        /// No progress bars.
        #[arg(long, short)]
        quiet: bool,
        /// As `build --memory`.
        #[arg(long)]
        memory: Option<MemorySize>,
    },
    /// Suggest an action chunk length K from the autocorrelation of the action signal, and check
    /// every profile's K; writes <output.dir>/audit/analyze.{json,html}.
    Analyze {
        spec: PathBuf,
        /// The channel to analyze (low-dimensional).
        #[arg(long, default_value = "action")]
        channel: String,
        /// Largest lag, in source steps (default: 200, or the longest profile K if larger;
        /// capped at the longest episode - 1).
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
        max_lag: Option<u64>,
    },
    /// Audit the timing of every episode; write `<output.dir>/audit/audit.json` and `report.html`.
    Audit { spec: PathBuf },
    /// Write a first spec for the dataset at PATH: its format, channels, rate, timing audit and
    /// a chunk length per profile from the action's autocorrelation, as a commented spec that
    /// `chunkc check` accepts. Never overwrites a file.
    Init {
        /// The dataset: a LeRobot folder, a Diffusion Policy zarr, a folder of ALOHA
        /// episode_<i>.hdf5 files, a robomimic/robosuite HDF5 file, or an RLDS (TFDS) folder.
        path: PathBuf,
        /// Where to write the spec.
        #[arg(long, default_value = "spec.toml")]
        out: PathBuf,
        /// The recording rate in Hz, for a source that stores none (else chunkc guesses and says so).
        #[arg(long)]
        fps: Option<f64>,
    },
    /// Print what `chunkc init` would find in the dataset at PATH, writing nothing.
    Inspect {
        path: PathBuf,
        /// The recording rate in Hz, for a source that stores none.
        #[arg(long)]
        fps: Option<f64>,
        /// Print JSON instead of the summary.
        #[arg(long)]
        json: bool,
    },
    /// Print the JSON Schema of the spec format.
    Schema,
    /// Write a synthetic source (with a matching spec.toml) into a new directory.
    Synth(SynthArgs),
}

#[derive(clap::Args)]
struct SynthArgs {
    /// The directory to create: it gets the source, spec.toml and (with faults) faults.json.
    out: PathBuf,
    #[arg(long, value_enum)]
    format: SynthFormat,
    #[arg(long, default_value_t = 10)]
    episodes: usize,
    /// Steps per episode (before any dropped frames).
    #[arg(long, default_value_t = 100)]
    steps: usize,
    #[arg(long, default_value_t = 14)]
    action_dim: usize,
    #[arg(long, default_value_t = 14)]
    state_dim: usize,
    #[arg(long, default_value_t = 0)]
    cameras: usize,
    /// Camera frame size, HEIGHTxWIDTH.
    #[arg(long, default_value = "96x96")]
    resolution: String,
    #[arg(long, default_value_t = 50.0)]
    fps: f64,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Faults, comma-separated: timing (drop:P, rate:HZ, jitter:F, dup:P) and data (frozen,
    /// clip, jump, lag:N, delta, scale:F, duplicate; each data fault in its own share).
    #[arg(long, value_delimiter = ',')]
    faults: Vec<synth::Fault>,
    /// The fraction of episodes that get the timing faults, and each data fault.
    #[arg(long, default_value_t = 0.2)]
    fault_fraction: f64,
    /// robomimic only: robosuite's older layout (no obs group; time in states[:, 0]).
    #[arg(long)]
    robosuite: bool,
    /// diffusion-policy-zarr only: rows per chunk of the low-dim arrays (default: about 1 MiB
    /// of rows).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    zarr_chunk_rows: Option<u64>,
    /// diffusion-policy-zarr only: columns per chunk of the low-dim arrays (default: all, as
    /// Diffusion Policy writes them; zarr-python's default chunking splits them).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    zarr_chunk_cols: Option<u64>,
    /// diffusion-policy-zarr only: the zarr format, 2 (Diffusion Policy's) or 3.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u8).range(2..=3))]
    zarr_format: u8,
}

#[derive(Clone, Copy, ValueEnum)]
enum SynthFormat {
    AlohaHdf5,
    RobomimicHdf5,
    DiffusionPolicyZarr,
    Lerobot,
    Rlds,
}

#[derive(Clone, Copy, ValueEnum)]
enum PlanFormat {
    Text,
    Json,
}

/// `specs/../out/pusht` -> `out/pusht`, for messages only (ignores symlinks on purpose).
fn tidy(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for part in path.components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}

// Long function: one arm per command, each a call into the library and its printout.
fn run(cli: Cli) -> Result<(), Error> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| Error::Internal(format!("thread pool: {e}")))?;
    }
    match cli.command {
        Command::Check { spec } => {
            let spec = LoadedSpec::load(&spec)?;
            let plan = commands::check(&spec)?;
            eprintln!(
                "ok: {} ({} episodes, {} profile(s))",
                spec.file.display(),
                plan.source.episodes,
                plan.profiles.len()
            );
        }
        Command::Plan {
            spec,
            format,
            shards,
        } => plan_command(&LoadedSpec::load(&spec)?, format, shards)?,
        Command::Build {
            spec,
            locked,
            quiet,
            shard: Some(shard),
            partials: Some(partials),
            memory,
        } => {
            let opts = BuildOptions {
                locked,
                progress: !quiet,
                memory: memory.map(|m| m.0),
            };
            shard_command(&LoadedSpec::load(&spec)?, shard, &partials, &opts)?;
        }
        Command::Merge {
            spec,
            partials,
            quiet,
            memory,
        } => {
            let spec = LoadedSpec::load(&spec)?;
            let report = commands::merge(
                &spec,
                &partials,
                &BuildOptions {
                    locked: false,
                    progress: !quiet,
                    memory: memory.map(|m| m.0),
                },
            )?;
            print_build(&report);
        }
        Command::Build {
            spec,
            locked,
            quiet,
            memory,
            ..
        } => {
            let spec = LoadedSpec::load(&spec)?;
            let report = commands::build(
                &spec,
                &BuildOptions {
                    locked,
                    progress: !quiet,
                    memory: memory.map(|m| m.0),
                },
            )?;
            print_build(&report);
        }
        Command::Analyze {
            spec,
            channel,
            max_lag,
        } => {
            let spec = LoadedSpec::load(&spec)?;
            let options = analyze::AnalyzeOptions {
                channel,
                max_lag: max_lag.map(|n| n as usize),
            };
            let (result, paths) = commands::analyze(&spec, &options)?;
            print!("{}", result.summary());
            eprintln!(
                "wrote {} and {}",
                tidy(&paths[0]).display(),
                tidy(&paths[1]).display()
            );
        }
        Command::Audit { spec } => {
            let spec = LoadedSpec::load(&spec)?;
            for (name, report, paths) in commands::audit_report(&spec)? {
                if !name.is_empty() {
                    println!("source `{name}`:");
                }
                print!("{}", report.summary());
                if let Some(doctor) = report.doctor_seconds {
                    eprintln!("the dataset doctor took {doctor:.2} s");
                }
                eprintln!(
                    "wrote {} and {}",
                    tidy(&paths[0]).display(),
                    tidy(&paths[1]).display()
                );
            }
        }
        Command::Init { path, out, fps } => {
            let options = init_options(fps)?;
            let (inspection, written) = commands::init(&path, &out, &options)?;
            eprint!("{}", init::summary::summary(&inspection));
            eprintln!(
                "wrote {}: `chunkc check {0}` then `chunkc build {0}`",
                tidy(&written).display()
            );
        }
        Command::Inspect { path, fps, json } => {
            let options = init_options(fps)?;
            // Nothing is written: the drafts' output directory only has to lie outside the source.
            let inspection = init::inspect(&path, &std::env::temp_dir(), &options)?;
            if json {
                print!("{}", inspection.to_json());
            } else {
                print!("{}", init::summary::summary(&inspection));
            }
        }
        Command::Schema => print!("{}", spec::json_schema()),
        Command::Synth(args) => {
            let opts = synth_options(&args)?;
            let spec = synth::generate(&opts, &args.out)?;
            eprintln!("wrote {}", tidy(&spec).display());
        }
    }
    Ok(())
}

/// `--fps` of `init` and `inspect`, checked.
fn init_options(fps: Option<f64>) -> Result<init::InitOptions, Error> {
    if let Some(f) = fps {
        if !(f.is_finite() && f > 0.0) {
            return Err(Error::Spec(format!(
                "error: --fps must be a positive rate in Hz, not {f}"
            )));
        }
    }
    Ok(init::InitOptions { fps })
}

/// `chunkc plan [--shards N]`: the plan, and the shard assignment when asked.
fn plan_command(spec: &LoadedSpec, format: PlanFormat, shards: Option<u64>) -> Result<(), Error> {
    let (source, plan) = commands::plan(spec)?;
    // Its source's fingerprint, which the text and the JSON show (hashed now if still pending).
    plan.source.fingerprint.get()?;
    let shards = shards
        .map(|n| plan::shards::estimate(&plan, source.as_ref(), n as usize))
        .transpose()?;
    let internal = |e: serde_json::Error| Error::Internal(e.to_string());
    match (format, &shards) {
        (PlanFormat::Text, _) => {
            print!("{}", plan::render_text(&plan));
            if let Some(s) = &shards {
                print!("{}", plan::shards::render_text(s));
            }
        }
        (PlanFormat::Json, None) => print!("{}", plan.to_json()),
        (PlanFormat::Json, Some(s)) => {
            let mut v: serde_json::Value =
                serde_json::from_str(&plan.to_json()).map_err(internal)?;
            v["shards"] = serde_json::to_value(s).map_err(internal)?;
            println!("{}", serde_json::to_string_pretty(&v).map_err(internal)?);
        }
    }
    Ok(())
}

/// `chunkc build --shard I/N --partials DIR`: one shard's partial, and what it holds.
fn shard_command(
    spec: &LoadedSpec,
    shard: plan::shards::Shard,
    partials: &Path,
    opts: &BuildOptions,
) -> Result<(), Error> {
    let r = commands::build_shard(spec, shard, partials, opts)?;
    eprintln!(
        "shard {}: episodes {}..{} -> {} ({:.1} MiB)",
        r.shard,
        r.episodes.start,
        r.episodes.end,
        tidy(&r.partial).display(),
        r.bytes as f64 / (1 << 20) as f64
    );
    if !r.excluded.is_empty() {
        eprintln!(
            "warning: {} episodes left out by [audit] non_finite: `chunkc merge` will refuse this run",
            r.excluded.len()
        );
    }
    Ok(())
}

/// What `chunkc build` says: what it built, or that nothing was to do.
fn print_build(report: &commands::BuildReport) {
    if report.built.is_empty() {
        eprintln!(
            "up to date: nothing to do ({} in {})",
            report.up_to_date.join(", "),
            tidy(&report.out_dir).display()
        );
    } else {
        eprintln!(
            "built {} in {}",
            report.built.join(", "),
            tidy(&report.out_dir).display()
        );
        if !report.up_to_date.is_empty() {
            eprintln!("up to date: {}", report.up_to_date.join(", "));
        }
    }
    for note in &report.video_notes {
        eprintln!("{note}");
    }
    for warning in &report.doctor_warnings {
        eprintln!("warning: {warning}");
    }
    if !report.doctor_warnings.is_empty() {
        eprintln!("`chunkc audit` writes which episodes the dataset doctor flagged, and why");
    }
    if let Some(doctor) = report.doctor_seconds {
        eprintln!(
            "the dataset doctor took {doctor:.2} s of {:.2} s (on by default; `[audit.doctor] enabled = false` skips it)",
            report.seconds
        );
    }
}

/// `chunkc synth`'s arguments as the library's options.
fn synth_options(args: &SynthArgs) -> Result<synth::SynthOptions, Error> {
    let (height, width) = args
        .resolution
        .split_once('x')
        .and_then(|(h, w)| Some((h.parse().ok()?, w.parse().ok()?)))
        .ok_or_else(|| {
            Error::Spec(format!(
                "chunkc synth: --resolution `{}` is not HEIGHTxWIDTH",
                args.resolution
            ))
        })?;
    Ok(synth::SynthOptions {
        format: match args.format {
            SynthFormat::AlohaHdf5 => SourceFormat::AlohaHdf5,
            SynthFormat::RobomimicHdf5 => SourceFormat::RobomimicHdf5,
            SynthFormat::DiffusionPolicyZarr => SourceFormat::DiffusionPolicyZarr,
            SynthFormat::Lerobot => SourceFormat::Lerobot,
            SynthFormat::Rlds => SourceFormat::Rlds,
        },
        episodes: args.episodes,
        steps: args.steps,
        action_dim: args.action_dim,
        state_dim: args.state_dim,
        cameras: args.cameras,
        height,
        width,
        fps: args.fps,
        seed: args.seed,
        faults: args.faults.clone(),
        fault_fraction: args.fault_fraction,
        robosuite: args.robosuite,
        zarr: synth::dp_zarr::ZarrLayout {
            chunk_rows: args.zarr_chunk_rows.map(|r| r as usize),
            chunk_cols: args.zarr_chunk_cols.map(|c| c as usize),
            format: args.zarr_format,
        },
    })
}

/// glibc's allocator, set for a build's pattern of allocations.
///
/// - One arena: episodes' frame buffers (megabytes each) are allocated on worker threads and
///   freed on the writing thread. glibc's per-thread arenas then keep freed buffers scattered
///   over several heaps, and peak memory grew with the number of episodes (145 MiB for 200 image
///   episodes against 117 MiB for 100); with one arena it stays flat (110 / 103 MiB).
/// - Fixed thresholds: blocks up to 32 MiB come from the heap, and the heap keeps up to 64 MiB
///   free at its top. With glibc's adaptive defaults, the short-lived blocks of a few hundred
///   kilobytes a build allocates and frees by the thousand (decoded chunks, HDF5's and parquet's
///   buffers, zstd's contexts) went back to the kernel and were faulted in again, zeroed, the
///   next time: 89,110 page faults against 76,267 for the doctor-off build of the bench's
///   5,000-episode zarr set, 0.80 s against 0.62 s (performance.md, "The allocator's
///   thresholds").
fn malloc_settings() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only sets allocator parameters; called before any other thread runs.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, 1);
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 64 << 20);
    }
}

/// Output piped into a program that stops reading (`chunkc plan | head`) ends chunkc quietly, as
/// it ends any Unix tool, not with a panic at the next print (Rust ignores `SIGPIPE`). chunkc
/// writes to no other pipe or socket, so nothing else meets the signal.
fn quiet_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: restores the signal's default action; called before any other thread runs.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    malloc_settings();
    quiet_on_closed_pipe();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{e}");
            ExitCode::from(e.exit_code() as u8)
        }
    }
}
