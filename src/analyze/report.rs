//! The chunk-size analysis as data: what `chunkc analyze` writes to `audit/analyze.json` and what
//! the HTML report draws. Lags are in source steps throughout; each profile's K is converted.

use serde::Serialize;

/// The autocorrelation of one channel, averaged over episodes, and what it says about each
/// profile's chunk length.
#[derive(Debug, Clone, Serialize)]
pub struct AnalyzeReport {
    /// The channel analyzed (`action` unless `--channel` says otherwise).
    pub channel: String,
    /// The rate the lags count steps of, in Hz.
    pub source_fps: f64,
    /// Episodes read, and their steps in all.
    pub episodes: usize,
    pub steps: usize,
    /// Lags `0..=max_lag` were computed (an episode contributes up to its length − 1).
    pub max_lag: usize,
    /// The suggested K is the first lag where the mean ACF drops below this.
    pub threshold: f64,
    /// The first lag ≥ 1 where `mean_acf` is below `threshold`, in source steps; `None` when it
    /// stays above up to `max_lag`.
    pub suggested_k: Option<usize>,
    /// `suggested_k` in seconds.
    pub suggested_seconds: Option<f64>,
    /// Per lag: the mean over dimensions of the dimensions' mean ACF.
    pub mean_acf: Vec<f64>,
    /// Per lag: how many episodes are long enough to have it (length > lag).
    pub episodes_at_lag: Vec<usize>,
    /// One entry per dimension of the channel.
    pub dims: Vec<DimAcf>,
    /// The warning thresholds for a profile's K.
    pub redundant_above: f64,
    pub independent_below: f64,
    /// In the spec's (sorted) profile order.
    pub profiles: Vec<ProfileCheck>,
    /// Findings about the data as a whole (constant dimensions, no lag below the threshold).
    pub warnings: Vec<String>,
}

/// One dimension's ACF, averaged over the episodes in which it varies.
#[derive(Debug, Clone, Serialize)]
pub struct DimAcf {
    pub dim: usize,
    /// Per lag, the mean over the episodes that vary in this dimension and are long enough;
    /// shorter than `max_lag + 1` when no such episode reaches the later lags, empty when the
    /// dimension is constant in every episode.
    pub acf: Vec<f64>,
    /// Source ids of the episodes in which this dimension is constant (left out of its mean).
    pub constant_episodes: Vec<u64>,
}

/// A profile's chunk length against the ACF.
#[derive(Debug, Clone, Serialize)]
pub struct ProfileCheck {
    pub name: String,
    pub fps: f64,
    /// Source steps per profile step (not an integer when the profile's rate is resampled).
    pub rate_factor: f64,
    /// K in the profile's steps, and converted to source steps (`chunk × rate_factor`, rounded).
    pub chunk: u32,
    pub chunk_source_steps: usize,
    /// The mean ACF at lag `chunk_source_steps`; `None` when that lag was not analyzed.
    pub acf_at_chunk: Option<f64>,
    /// The suggested K in this profile's steps (rounded up).
    pub suggested_chunk: Option<usize>,
    /// Why this K deserves a second look, if it does.
    pub warning: Option<String>,
}
