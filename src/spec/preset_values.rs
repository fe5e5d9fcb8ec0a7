//! What each preset supplies: one table of values per preset, each with the codebase it comes
//! from (see TARGETS.md, "Default chunk parameters"). [`super::preset`] expands a profile over
//! them.

use super::model::{
    Alignment, ImageEncoding, LerobotVersion, NormalizeMode, OutputFormat, Padding, Preset,
    StatsFormat, StatsPopulation,
};

/// The values a preset supplies (see TARGETS.md, "Default chunk parameters").
pub(super) struct PresetValues {
    pub(super) fps: Option<f64>,
    pub(super) chunk: Option<u32>,
    pub(super) obs_history: u32,
    pub(super) executes: Option<u32>,
    pub(super) alignment: Alignment,
    pub(super) padding: Padding,
    pub(super) normalize_lowdim: NormalizeMode,
    pub(super) normalize_multidim: NormalizeMode,
    pub(super) stats_formats: &'static [StatsFormat],
    pub(super) stats_population: Option<StatsPopulation>,
    /// The output format a preset implies (`None`: the default, `hdf5`).
    pub(super) format: Option<OutputFormat>,
    /// The LeRobot layout a preset implies (`None`: the default, v3.0).
    pub(super) lerobot_version: Option<LerobotVersion>,
    /// How a parquet profile stores frames (`None`: the default, PNG).
    pub(super) image_encoding: Option<ImageEncoding>,
}

// Long function: one table of values per preset, each with where it comes from.
pub(super) fn preset_values(preset: Preset) -> PresetValues {
    use NormalizeMode as N;
    let base = PresetValues {
        fps: None,
        chunk: None,
        obs_history: 1,
        executes: None,
        alignment: Alignment::Current,
        padding: Padding::Edge,
        normalize_lowdim: N::None,
        normalize_multidim: N::None,
        stats_formats: &[],
        stats_population: None,
        format: None,
        lerobot_version: None,
        image_encoding: None,
    };
    // openpi: the action horizon at the dataset rate, statistics over every sample's chunk
    // (`compute_norm_stats`), quantiles for every model but pi0 (`use_quantile_norm`).
    let openpi = PresetValues {
        chunk: Some(50),
        normalize_lowdim: N::Quantile,
        normalize_multidim: N::Quantile,
        stats_formats: &[StatsFormat::Openpi],
        stats_population: Some(StatsPopulation::Windows),
        ..base
    };
    let dp = PresetValues {
        fps: Some(10.0),
        chunk: Some(16),
        obs_history: 2,
        executes: Some(8),
        alignment: Alignment::DiffusionPolicy,
        normalize_lowdim: N::Limits,
        normalize_multidim: N::Limits,
        stats_formats: &[StatsFormat::DiffusionPolicy],
        ..base
    };
    match preset {
        // ACT: K=100 at 50 Hz, the current observation only, z-score (get_norm_stats).
        Preset::Act => PresetValues {
            fps: Some(50.0),
            chunk: Some(100),
            normalize_lowdim: N::Zscore,
            normalize_multidim: N::Zscore,
            stats_formats: &[StatsFormat::Act],
            ..base
        },
        // Diffusion Policy: horizon 16, n_obs_steps 2, n_action_steps 8, LinearNormalizer limits.
        Preset::DiffusionPolicy => dp,
        // 3D Diffusion Policy: the same, with point clouds (matrix-valued channels) unnormalized.
        Preset::Dp3 => PresetValues {
            normalize_multidim: N::None,
            ..dp
        },
        // High-frequency Diffusion Policy: K=32 at 20 Hz, three observations, zero + mask.
        Preset::DiffusionPolicyHighfreq => PresetValues {
            fps: Some(20.0),
            chunk: Some(32),
            obs_history: 3,
            executes: Some(16),
            padding: Padding::Zero,
            ..dp
        },
        // LeRobot ACT: chunk_size 100, n_obs_steps 1, MEAN_STD, every frame a sample.
        Preset::LerobotAct => PresetValues {
            chunk: Some(100),
            normalize_lowdim: N::LerobotMeanStd,
            normalize_multidim: N::LerobotMeanStd,
            stats_formats: &[StatsFormat::Lerobot],
            ..base
        },
        // LeRobot Diffusion: horizon 64, n_obs_steps 2, actions from the first observation
        // frame (delta indices start at 1 - n_obs_steps), MIN_MAX, every frame a sample.
        Preset::LerobotDiffusion => PresetValues {
            chunk: Some(64),
            obs_history: 2,
            alignment: Alignment::DiffusionPolicy,
            normalize_lowdim: N::LerobotMinMax,
            normalize_multidim: N::LerobotMinMax,
            stats_formats: &[StatsFormat::Lerobot],
            ..base
        },
        // pi0 (Pi0Config: action_horizon 50): z-score with openpi's epsilon.
        Preset::Pi0 => PresetValues {
            normalize_lowdim: N::OpenpiZscore,
            normalize_multidim: N::OpenpiZscore,
            ..openpi
        },
        // pi0.5 (Pi0Config(pi05=True): action_horizon 50), and `openpi`, its alias.
        Preset::Pi05 | Preset::Openpi => openpi,
        // pi0-FAST (Pi0FASTConfig: action_horizon 32).
        Preset::Pi0Fast => PresetValues {
            chunk: Some(32),
            ..openpi
        },
        // GR00T N1.7 (Isaac-GR00T's modality configs: action `delta_indices` range(16), state
        // and video [0]): a sample only where its whole chunk is in the episode (length - 16 + 1
        // per episode), q01/q99 min-max normalization clipped to [-1, 1], and the LeRobot v2.1
        // dataset its loader reads, cameras as the mp4s it decodes.
        Preset::Groot => PresetValues {
            chunk: Some(16),
            padding: Padding::Truncate,
            normalize_lowdim: N::GrootQuantile,
            normalize_multidim: N::GrootQuantile,
            format: Some(OutputFormat::Parquet),
            lerobot_version: Some(LerobotVersion::V21),
            image_encoding: Some(ImageEncoding::Video),
            ..base
        },
    }
}
