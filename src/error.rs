//! The one error type every stage returns, and the exit code each kind maps to.
//!
//! Messages are complete sentences that name the place: the spec key (already rendered with its
//! `file:line:col` excerpt by `spec::diagnostic`), or the episode, channel and step.

use std::path::PathBuf;

/// Exit codes are part of the CLI contract (documented in the book's error chapter).
pub mod exit {
    /// The spec is malformed or asks for something impossible.
    pub const SPEC: i32 = 2;
    /// The source dataset is missing, unreadable or inconsistent.
    pub const SOURCE: i32 = 3;
    /// Writing the outputs failed (disk, permissions, HDF5 library).
    pub const OUTPUT: i32 = 4;
    /// `--locked` was given and the outputs are not up to date.
    pub const LOCKED: i32 = 5;
    /// Another build holds the output directory's build lock.
    pub const BUSY: i32 = 6;
    /// A bug in chunkc: a job panicked or an invariant broke.
    pub const INTERNAL: i32 = 70;
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A spec error, already rendered with the excerpt that locates it.
    #[error("{0}")]
    Spec(String),
    /// A problem with the source dataset.
    #[error("{0}")]
    Source(String),
    /// Writing outputs failed.
    #[error("{0}")]
    Output(String),
    #[error("{context}: {source}")]
    Io {
        context: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Locked(String),
    /// Another build of the same output directory is running.
    #[error("{0}")]
    Busy(String),
    #[error("internal error: {0}")]
    Internal(String),
    /// Not a failure: a source opened with an empty `[source.channels]` (a spec always maps
    /// `action`; only `chunkc init` and `inspect` open one so) stops where its channels would be
    /// mapped and hands back every key it offers (`source::offered`).
    #[error("{}: the source offers {} keys and the spec maps none", .0.place, .0.keys.len())]
    Offered(Box<Offer>),
}

/// The keys a source offers, as `Error::Offered` carries them.
#[derive(Debug, Clone)]
pub struct Offer {
    /// The file or table the keys were listed from (shown in messages).
    pub place: String,
    /// Each key, its per-step shape and its element type as the source names it.
    pub keys: Vec<(String, Vec<usize>, String)>,
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn exit_code(&self) -> i32 {
        match self {
            Error::Spec(_) | Error::Offered(_) => exit::SPEC,
            Error::Source(_) => exit::SOURCE,
            Error::Output(_) | Error::Io { .. } => exit::OUTPUT,
            Error::Locked(_) => exit::LOCKED,
            Error::Busy(_) => exit::BUSY,
            Error::Internal(_) => exit::INTERNAL,
        }
    }

    pub fn source(msg: impl Into<String>) -> Self {
        Error::Source(msg.into())
    }

    pub fn output(msg: impl Into<String>) -> Self {
        Error::Output(msg.into())
    }

    pub fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io {
            context: context.into(),
            source,
        }
    }

    pub fn io_path(verb: &str, path: &std::path::Path, source: std::io::Error) -> Self {
        Error::io(format!("cannot {verb} {}", path.display()), source)
    }
}

/// Attach a path to an I/O result: `fs::read(p).at("read", p)?`.
pub trait IoContext<T> {
    fn at(self, verb: &str, path: impl Into<PathBuf>) -> Result<T>;
}

impl<T> IoContext<T> for std::io::Result<T> {
    fn at(self, verb: &str, path: impl Into<PathBuf>) -> Result<T> {
        self.map_err(|e| Error::io_path(verb, &path.into(), e))
    }
}

impl From<hdf5::Error> for Error {
    fn from(e: hdf5::Error) -> Self {
        Error::Output(format!("HDF5: {e}"))
    }
}

/// The results of a parallel map, in item order, or the first error in item order. rayon's own
/// `collect::<Result<_>>()` returns whichever failure a thread met first, so when several items
/// fail (two episodes reading one damaged chunk, two damaged shards) the message would depend on
/// timing; every parallel map over episodes, files or shards gathers through here instead.
pub fn in_order<T: Send, E: Send>(
    results: impl rayon::iter::IndexedParallelIterator<Item = std::result::Result<T, E>>,
) -> std::result::Result<Vec<T>, E> {
    results.collect::<Vec<_>>().into_iter().collect()
}
