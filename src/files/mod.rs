//! A leaf: how chunkc's commands put files in the output directory. The reports' several files
//! written as one (`atomic`), and the names a build creates directly under the output directory,
//! which the spec's output-location rule ([`crate::spec::check_output_location`]) and the
//! build's staging both need; they live below every stage so that neither imports the other.

mod atomic;

pub use atomic::write_files;

/// The directory a build stages its files in, under the output directory (renamed into place,
/// then removed).
pub const STAGING_DIR: &str = ".chunkc-staging";
/// The file a build holds locked while it runs, in the output directory.
pub const BUILD_LOCK_FILE: &str = ".chunkc-build.lock";
