//! What `chunkc synth --faults` did to an episode, as `faults.json` records it: the truth the
//! audit and the dataset doctor are measured against.

/// One injected fault (timing or data), as recorded in `faults.json`.
#[derive(Debug, Clone, serde::Serialize)]
#[serde(tag = "fault", rename_all = "snake_case")]
pub enum Injected {
    /// These steps (of the generated episode, before dropping) were removed, data and time.
    Drop { steps: Vec<usize> },
    /// Timestamps advance by `1 / actual_fps` while the dataset claims its nominal rate.
    Rate { actual_fps: f64 },
    /// Each timestamp moved by a uniform offset in `[-fraction, fraction] / fps` (the first
    /// stays at 0).
    Jitter { fraction: f64 },
    /// These steps (of the stored episode) repeat the previous step's timestamp.
    Duplicate { steps: Vec<usize> },
    /// Action dimension `dim` holds its value from step `from` on.
    Frozen { dim: usize, from: usize },
    /// Action dimension `dim` saturates at `bound` (its `side`, "max" or "min"); `steps` were cut.
    Clip {
        dim: usize,
        bound: f64,
        side: &'static str,
        steps: usize,
    },
    /// One-step spikes of `sizes` added to action dimension `dim` at `steps`.
    Jump {
        dim: usize,
        steps: Vec<usize>,
        sizes: Vec<f64>,
    },
    /// The actions are recorded `steps` late against the state.
    Lag { steps: i32 },
    /// The actions are recorded as target minus current state.
    Delta,
    /// The actions are multiplied by `factor` (other units).
    Scale { factor: f64 },
    /// The episode is a near-copy of episode `of`.
    DuplicateEpisode { of: u64 },
}
