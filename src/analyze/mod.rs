//! `chunkc analyze`: how long should an action chunk be? The autocorrelation (ACF) of the action
//! signal, per dimension and averaged over episodes, says how many steps ahead actions still
//! resemble the current one. The first lag where the mean ACF drops below 0.3 is the suggested
//! K; a profile whose K still has an ACF above 0.5 repeats itself within a chunk, one below 0.1
//! predicts actions that are nearly independent of the first.
//!
//! Choices (documented in the book's "Choosing K" chapter):
//! - The analysis runs at the source rate on the raw source (no audit repairs, no decimation);
//!   each profile's K is converted to source steps (`chunk × rate_factor`) before it is looked up.
//! - Lags `0..=max_lag`, `max_lag` = `--max-lag`, else the larger of 200 and the longest profile
//!   K in source steps, capped at the longest episode − 1. An episode shorter than a lag does
//!   not contribute to it (each lag is averaged over the episodes that have it).
//! - A dimension that is constant in an episode has no ACF there (zero variance) and is left out
//!   of that episode's contribution; a dimension constant everywhere is left out of the mean.
//!
//! Files: `acf` (the formula, statsmodels' numbers), `average` (over episodes and dimensions),
//! `report` ([`AnalyzeReport`], written as `audit/analyze.json`).

mod acf;
mod average;
mod report;

use std::path::{Path, PathBuf};

pub use acf::acf;
pub use report::{AnalyzeReport, DimAcf, ProfileCheck};

use crate::error::{Error, Result};
use crate::source::{self, ChannelData, ChannelKind};
use crate::spec::LoadedSpec;

/// The suggested K is the first lag where the mean ACF is below this.
pub const THRESHOLD: f64 = 0.3;
/// A profile's K with a mean ACF above this gets a "redundant chunk" warning.
pub const REDUNDANT_ABOVE: f64 = 0.5;
/// A profile's K with a mean ACF below this gets a "nearly independent" warning.
pub const INDEPENDENT_BELOW: f64 = 0.1;
/// Lags analyzed when `--max-lag` is not given (raised to cover every profile's K).
pub const DEFAULT_MAX_LAG: usize = 200;

#[derive(Debug, Clone)]
pub struct AnalyzeOptions {
    /// The channel to analyze (a low-dimensional one; `action` by default).
    pub channel: String,
    pub max_lag: Option<usize>,
}

impl Default for AnalyzeOptions {
    fn default() -> Self {
        AnalyzeOptions {
            channel: "action".into(),
            max_lag: None,
        }
    }
}

/// Reads the channel of every episode and computes the report.
// Long function: the read and the per-dimension autocorrelation share their buffers and progress bar.
pub fn analyze(spec: &LoadedSpec, options: &AnalyzeOptions) -> Result<AnalyzeReport> {
    let name = &options.channel;
    if spec.is_mixture() {
        return Err(spec.error_at(
            &["sources"],
            "`chunkc analyze` reads one source; this spec is a mixture".to_string(),
            Some("analyze each source with a spec of its own `[source]`".into()),
        ));
    }
    if !spec.source().channels.contains_key(name) {
        let known: Vec<&str> = spec.source().channels.keys().map(|k| k.as_str()).collect();
        return Err(spec.error_at(
            &["source", "channels"],
            format!("`chunkc analyze --channel {name}`: the spec maps no channel `{name}`"),
            Some(format!("channels: {}", known.join(", "))),
        ));
    }
    if options.max_lag == Some(0) {
        return Err(Error::Spec("`--max-lag` must be at least 1".into()));
    }
    crate::spec::check_output_location(spec, &spec.resolve(&spec.spec.output.dir))?;
    // Only the analyzed channel is opened, so images are never read.
    let mut narrow = spec.clone();
    if let Some(source) = narrow.spec.source.as_mut() {
        source.channels.retain(|k, _| k == name);
    }
    let source = source::open(&narrow)?;
    let manifest = source.manifest();
    let info = manifest
        .channels
        .iter()
        .find(|c| &c.name == name)
        .ok_or_else(|| Error::Internal(format!("channel `{name}` missing from the manifest")))?;
    if info.kind != ChannelKind::Lowdim {
        return Err(spec.error_at(
            &["source", "channels", name],
            format!(
                "channel `{name}` holds images; `chunkc analyze` needs a low-dimensional channel"
            ),
            None,
        ));
    }
    let width = info.width();
    let position = manifest
        .channels
        .iter()
        .position(|c| &c.name == name)
        .unwrap_or(0);
    let longest = manifest.episodes.iter().map(|e| e.len).max().unwrap_or(0);
    if longest < 2 {
        return Err(Error::source(format!(
            "{}: no episode has two steps; there is nothing to correlate",
            spec.source().path
        )));
    }

    let profiles = profile_checks(spec, manifest.fps)?;
    let longest_k = profiles
        .iter()
        .map(|p| p.chunk_source_steps)
        .max()
        .unwrap_or(0);
    let max_lag = options
        .max_lag
        .unwrap_or(DEFAULT_MAX_LAG.max(longest_k))
        .min(longest - 1);

    let mut acc = average::Accumulator::new(width, max_lag);
    let mut steps = 0;
    for index in 0..manifest.episodes.len() {
        let episode = source.read_episode(index)?;
        let ChannelData::Lowdim(values) = &episode.channels[position] else {
            return Err(Error::Internal(format!(
                "channel `{name}` is not low-dimensional"
            )));
        };
        steps += episode.len;
        acc.add(episode.id, values, width);
    }
    let (dims, mean_acf, episodes_at_lag) = acc.finish();
    Ok(finish(
        name,
        manifest.fps,
        manifest.episodes.len(),
        steps,
        max_lag,
        dims,
        mean_acf,
        episodes_at_lag,
        profiles,
    ))
}

/// Every profile's K in source steps (its verdict is filled in by [`finish`]); refuses a
/// profile that would upsample.
fn profile_checks(spec: &LoadedSpec, source_fps: f64) -> Result<Vec<ProfileCheck>> {
    let mut profiles = Vec::new();
    for p in &spec.profiles {
        let fps = p.fps.unwrap_or(source_fps);
        // Only refuses upsampling; the method does not matter for the step ratio.
        crate::plan::conversion(source_fps, fps, spec.spec.audit.resample).map_err(|msg| {
            spec.error_at(
                &["profiles", &p.name, "fps"],
                format!("profile `{}` runs at {msg}", p.name),
                None,
            )
        })?;
        let rate_factor = source_fps / fps;
        profiles.push(ProfileCheck {
            name: p.name.clone(),
            fps,
            rate_factor,
            chunk: p.chunk,
            chunk_source_steps: (p.chunk as f64 * rate_factor).round() as usize,
            acf_at_chunk: None,
            suggested_chunk: None,
            warning: None,
        });
    }
    Ok(profiles)
}

/// The suggested K, each profile's verdict, and the dataset-wide warnings.
#[allow(clippy::too_many_arguments)]
fn finish(
    channel: &str,
    source_fps: f64,
    episodes: usize,
    steps: usize,
    max_lag: usize,
    dims: Vec<DimAcf>,
    mean_acf: Vec<f64>,
    episodes_at_lag: Vec<usize>,
    mut profiles: Vec<ProfileCheck>,
) -> AnalyzeReport {
    let suggested_k = (1..mean_acf.len()).find(|&k| mean_acf[k] < THRESHOLD);
    let mut warnings = Vec::new();
    for d in &dims {
        if d.acf.is_empty() {
            warnings.push(format!(
                "{channel}[{}] is constant in every episode; left out of the mean",
                d.dim
            ));
        } else if !d.constant_episodes.is_empty() {
            warnings.push(format!(
                "{channel}[{}] is constant in {} episode(s); left out of its mean there",
                d.dim,
                d.constant_episodes.len()
            ));
        }
    }
    if suggested_k.is_none() {
        warnings.push(format!(
            "the mean ACF stays above {THRESHOLD} up to lag {}; no K suggested (try a larger --max-lag)",
            mean_acf.len().saturating_sub(1)
        ));
    }
    for p in &mut profiles {
        p.acf_at_chunk = mean_acf.get(p.chunk_source_steps).copied();
        p.suggested_chunk = suggested_k.map(|k| (k as f64 / p.rate_factor - 1e-9).ceil() as usize);
        let k = p.chunk_source_steps;
        p.warning = match p.acf_at_chunk {
            None => Some(format!(
                "not analyzed: K = {} ({k} source steps) is beyond the lags analyzed (up to {}); raise --max-lag or check that episodes are that long",
                p.chunk,
                mean_acf.len().saturating_sub(1)
            )),
            Some(r) if r > REDUNDANT_ABOVE => Some(format!(
                "redundant chunk: the ACF at K = {} ({k} source steps) is {r:.3} > {REDUNDANT_ABOVE}; the chunk's last actions still repeat its first, a shorter K would do",
                p.chunk
            )),
            Some(r) if r < INDEPENDENT_BELOW => Some(format!(
                "long chunk: the ACF at K = {} ({k} source steps) is {r:.3} < {INDEPENDENT_BELOW}; the chunk's later actions are nearly independent of its start",
                p.chunk
            )),
            Some(_) => None,
        };
    }
    AnalyzeReport {
        channel: channel.to_string(),
        source_fps,
        episodes,
        steps,
        max_lag,
        threshold: THRESHOLD,
        suggested_k,
        suggested_seconds: suggested_k.map(|k| k as f64 / source_fps),
        mean_acf,
        episodes_at_lag,
        dims,
        redundant_above: REDUNDANT_ABOVE,
        independent_below: INDEPENDENT_BELOW,
        profiles,
        warnings,
    }
}

/// Where `chunkc analyze` writes: `<output.dir>/audit/`.
pub fn audit_dir(spec: &LoadedSpec) -> PathBuf {
    spec.resolve(&spec.spec.output.dir).join("audit")
}

/// Writes `analyze.json` and `analyze.html` into `dir` and returns their paths, both renamed into
/// place only when both were written.
pub fn write(dir: &Path, report: &AnalyzeReport, html: &str) -> Result<Vec<PathBuf>> {
    let json = serde_json::to_string_pretty(report)
        .map_err(|e| Error::Internal(format!("analyze.json: {e}")))?
        + "\n";
    crate::files::write_files(
        dir,
        &[
            ("analyze.json", json.into_bytes()),
            ("analyze.html", html.as_bytes().to_vec()),
        ],
    )
}

impl AnalyzeReport {
    /// The lines `chunkc analyze` prints.
    pub fn summary(&self) -> String {
        let mut out = format!(
            "{}: {} dimension(s), {} episodes, {} steps at {} Hz; lags 0..={}\n",
            self.channel,
            self.dims.len(),
            self.episodes,
            self.steps,
            self.source_fps,
            self.max_lag
        );
        match self.suggested_k {
            Some(k) => out += &format!(
                "suggested K: {k} steps at {} Hz ({:.2} s): the first lag where the mean ACF ({:.3}) is below {}\n",
                self.source_fps,
                k as f64 / self.source_fps,
                self.mean_acf[k],
                self.threshold
            ),
            None => out += &format!("suggested K: none (the mean ACF stays above {})\n", self.threshold),
        }
        for p in &self.profiles {
            let acf = p
                .acf_at_chunk
                .map_or("n/a".to_string(), |r| format!("{r:.3}"));
            out += &format!(
                "  profile {}: K = {} at {} Hz ({} source steps), ACF {acf}{}\n",
                p.name,
                p.chunk,
                p.fps,
                p.chunk_source_steps,
                p.suggested_chunk
                    .map_or(String::new(), |k| format!(", suggested K at its rate: {k}"))
            );
            if let Some(w) = &p.warning {
                out += &format!("    warning: {w}\n");
            }
        }
        for w in &self.warnings {
            out += &format!("warning: {w}\n");
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(name: &str, chunk: u32, factor: usize) -> ProfileCheck {
        ProfileCheck {
            name: name.into(),
            fps: 10.0 / factor as f64,
            rate_factor: factor as f64,
            chunk,
            chunk_source_steps: chunk as usize * factor,
            acf_at_chunk: None,
            suggested_chunk: None,
            warning: None,
        }
    }

    #[test]
    fn suggested_k_and_profile_warnings_follow_the_thresholds() {
        // Mean ACF 1, 0.9, 0.8, ..., 0.0 (lag 10).
        let mean: Vec<f64> = (0..=10).map(|k| 1.0 - k as f64 / 10.0).collect();
        let dims = vec![DimAcf {
            dim: 0,
            acf: mean.clone(),
            constant_episodes: vec![],
        }];
        let profiles = vec![
            check("short", 2, 1),
            check("fine", 3, 2),
            check("long", 10, 1),
            check("beyond", 6, 2),
        ];
        let r = finish("action", 10.0, 1, 11, 10, dims, mean, vec![1; 11], profiles);
        // 0.3 at lag 7 is not below 0.3 (rounding aside): lag 8 (0.2) is the first below.
        assert_eq!(r.suggested_k, Some(8));
        assert!(r.profiles[0]
            .warning
            .as_deref()
            .unwrap()
            .starts_with("redundant"));
        assert_eq!(r.profiles[1].acf_at_chunk, Some(0.4));
        assert!(r.profiles[1].warning.is_none());
        assert_eq!(r.profiles[1].suggested_chunk, Some(4));
        assert!(r.profiles[2]
            .warning
            .as_deref()
            .unwrap()
            .starts_with("long chunk"));
        assert!(r.profiles[3].acf_at_chunk.is_none());
        assert!(r.profiles[3].warning.as_deref().unwrap().contains("beyond"));
        assert!(r.summary().contains("suggested K: 8 steps"));
    }
}
