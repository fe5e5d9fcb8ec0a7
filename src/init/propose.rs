//! The numbers `chunkc init` proposes: the source rate where the source stores none, and each
//! profile's rate and chunk length K from the action's autocorrelation.

use serde::Serialize;

use crate::spec::SourceFormat;

/// The shortest chunk `init` proposes for ACT, in seconds.
pub const MIN_CHUNK_SECONDS: f64 = 0.25;

/// Where the rate came from.
#[derive(Debug, Clone, Serialize)]
pub struct Rate {
    pub fps: f64,
    /// `meta/info.json`, the timestamps, `--fps`, or the guess and its reason.
    pub origin: String,
    /// A guess the user should confirm (the spec says so next to `fps`).
    pub guessed: bool,
}

/// Open X-Embodiment datasets' control rates, by TFDS dataset name (the OXE dataset table).
const OXE_RATES: &[(&str, f64)] = &[
    ("bridge", 5.0),
    ("bridge_dataset", 5.0),
    ("fractal20220817_data", 3.0),
    ("kuka", 10.0),
    ("taco_play", 15.0),
    ("jaco_play", 10.0),
    ("language_table", 10.0),
    ("droid", 15.0),
    ("toto", 30.0),
    ("viola", 20.0),
    ("berkeley_autolab_ur5", 5.0),
    ("roboturk", 10.0),
    ("bc_z", 10.0),
];

/// The rate of a source that stores none, or `None` when it stores one (LeRobot) or has
/// timestamps (robosuite): the adapter then reads it. `name` is the dataset's directory name.
pub fn rate_guess(format: SourceFormat, name: &str, timestamps: bool) -> Option<Rate> {
    let guess = |fps: f64, why: &str| {
        Some(Rate {
            fps,
            origin: why.to_string(),
            guessed: true,
        })
    };
    match format {
        SourceFormat::Lerobot => None,
        SourceFormat::RobomimicHdf5 if timestamps => None,
        SourceFormat::RobomimicHdf5 => guess(
            20.0,
            "guessed: the file stores no rate or timestamps; robomimic's datasets are 20 Hz",
        ),
        SourceFormat::AlohaHdf5 => guess(
            50.0,
            "guessed: ALOHA episodes store no rate; ACT records at 50 Hz (DT = 0.02)",
        ),
        SourceFormat::DiffusionPolicyZarr => guess(
            10.0,
            "guessed: a replay buffer stores no rate; Diffusion Policy's datasets are 10 Hz",
        ),
        SourceFormat::Rlds => match OXE_RATES.iter().find(|(n, _)| *n == name) {
            Some((_, fps)) => Some(Rate {
                fps: *fps,
                origin: format!("Open X-Embodiment's table: `{name}` is recorded at {fps} Hz"),
                guessed: false,
            }),
            None => guess(
                10.0,
                "guessed: RLDS stores no rate and this dataset is not in chunkc's Open X-Embodiment table",
            ),
        },
    }
}

/// One profile `chunkc init` writes.
#[derive(Debug, Clone, Serialize)]
pub struct ProposedProfile {
    pub name: String,
    pub preset: String,
    /// `None`: the preset's rate is the source's, nothing to set.
    pub fps: Option<f64>,
    pub chunk: u32,
    pub executes: Option<u32>,
    pub format: Option<String>,
    /// The reasoning, one comment line each.
    pub why: Vec<String>,
}

/// The action ACF's answer at the source rate.
#[derive(Debug, Clone, Serialize)]
pub struct AcfSummary {
    /// First lag (source steps) where the mean ACF falls below the threshold.
    pub suggested_k: Option<usize>,
    pub threshold: f64,
    pub max_lag: usize,
    /// The mean ACF by lag (0..=max_lag).
    pub mean_acf: Vec<f64>,
}

impl AcfSummary {
    fn at(&self, lag: usize) -> Option<f64> {
        self.mean_acf.get(lag).copied()
    }
}

fn fmt_hz(fps: f64) -> String {
    if fps.fract() == 0.0 {
        format!("{fps:.0} Hz")
    } else {
        format!("{fps} Hz")
    }
}

/// The largest whole-number divisor of the source rate that is at most `target`, so that the
/// profile's rate is the source's decimated by an integer (chunkc converts rates exactly then).
fn decimated(source_fps: f64, target: f64) -> f64 {
    if source_fps <= target || source_fps.fract() != 0.0 {
        return source_fps;
    }
    let n = source_fps as u64;
    (1..=n)
        .filter(|d| n.is_multiple_of(*d))
        .map(|d| (n / d) as f64)
        .find(|f| *f <= target)
        .unwrap_or(source_fps)
}

/// K in a profile's steps: the ACF's lag (source steps) at the profile's rate, at least `min`,
/// at most `cap` (the shortest episode at that rate, so every episode gives a window).
fn k_at(acf: &AcfSummary, factor: f64, min: u32, cap: u32) -> Option<u32> {
    let k = acf.suggested_k?;
    let steps = (k as f64 / factor).ceil() as u32;
    Some(steps.max(min).min(cap.max(min)))
}

/// The action's ACF, said for a comment line.
fn acf_line(acf: &AcfSummary, source_fps: f64) -> String {
    match acf.suggested_k {
        Some(k) => format!(
            "the action's mean autocorrelation falls below {} at lag {k} ({:.2} s at {})",
            acf.threshold,
            k as f64 / source_fps,
            fmt_hz(source_fps)
        ),
        None => format!(
            "the action's mean autocorrelation stays above {} up to lag {}: the preset's K is kept",
            acf.threshold, acf.max_lag
        ),
    }
}

/// The mean ACF at a profile's K (`factor` source steps a profile step), for a comment line.
fn acf_at(acf: &AcfSummary, k: u32, factor: f64) -> Option<String> {
    let lag = (k as f64 * factor).round() as usize;
    acf.at(lag)
        .map(|v| format!("mean ACF at K = {k} ({lag} source steps): {v:.2}"))
}

/// ACT at the source rate, K from the ACF: at least a quarter second, at most the shortest
/// episode.
fn act(source_fps: f64, shortest: usize, acf: Option<&AcfSummary>) -> ProposedProfile {
    let mut why = vec![format!(
        "ACT at the source rate ({}); the preset's K = 100 is 2 s at 50 Hz",
        fmt_hz(source_fps)
    )];
    let cap = shortest as u32;
    // A chunk shorter than a quarter second plans nothing ahead, however fast the ACF decays.
    let floor = ((source_fps * MIN_CHUNK_SECONDS).ceil() as u32).max(2);
    let chunk = match acf.zip(acf.and_then(|a| k_at(a, 1.0, floor, cap))) {
        Some((a, k)) => {
            why.push(acf_line(a, source_fps));
            let lag = a.suggested_k.unwrap_or(0) as u32;
            if lag < floor && k == floor {
                why.push(format!(
                    "raised to {k} steps: at least {MIN_CHUNK_SECONDS} s of actions per chunk"
                ));
            }
            if lag > cap {
                why.push(format!("capped at the shortest episode ({shortest} steps)"));
            }
            why.extend(acf_at(a, k, 1.0));
            k
        }
        None => {
            why.extend(acf.map(|a| acf_line(a, source_fps)));
            100.min(cap.max(2))
        }
    };
    ProposedProfile {
        name: "act".into(),
        preset: "act".into(),
        fps: (source_fps != 50.0).then_some(source_fps),
        chunk,
        executes: None,
        format: None,
        why,
    }
}

/// Diffusion Policy: 10 Hz where the source rate divides down to it, the horizon a multiple of 4
/// (at least 8), executing half of it.
fn diffusion_policy(source_fps: f64, shortest: usize, acf: Option<&AcfSummary>) -> ProposedProfile {
    let dp_fps = decimated(source_fps, 10.0);
    let factor = source_fps / dp_fps;
    let cap = (shortest as f64 / factor).floor() as u32;
    let mut why = vec![if dp_fps == source_fps {
        format!("Diffusion Policy at the source rate ({})", fmt_hz(dp_fps))
    } else {
        format!(
            "Diffusion Policy at {} (the source's {} decimated by {factor}), as its real-robot datasets",
            fmt_hz(dp_fps),
            fmt_hz(source_fps)
        )
    }];
    let chunk = match acf.zip(acf.and_then(|a| k_at(a, factor, 8, cap.max(8)))) {
        Some((a, k)) => {
            why.push(acf_line(a, source_fps));
            let rounded = k.div_ceil(4) * 4;
            let lag = a.suggested_k.unwrap_or(0) as f64 / factor;
            why.push(format!(
                "horizon {rounded}: that lag is {:.0} steps at {}; at least 8 and a multiple of 4, which its U-Net's two down-samplings need (DP's own: 16)",
                lag.ceil(),
                fmt_hz(dp_fps)
            ));
            why.extend(acf_at(a, rounded, factor));
            rounded
        }
        None => {
            why.extend(acf.map(|a| acf_line(a, source_fps)));
            16
        }
    };
    ProposedProfile {
        name: "dp".into(),
        preset: "diffusion_policy".into(),
        fps: (dp_fps != 10.0).then_some(dp_fps),
        chunk,
        executes: (chunk != 16).then_some(chunk / 2),
        format: None,
        why,
    }
}

/// What this dataset gets: ACT and Diffusion Policy always, DP3 with point clouds, a LeRobot
/// export unless the source is LeRobot already.
pub fn profiles(
    format: SourceFormat,
    source_fps: f64,
    shortest: usize,
    acf: Option<&AcfSummary>,
    point_clouds: bool,
) -> Vec<ProposedProfile> {
    let act = act(source_fps, shortest, acf);
    let dp = diffusion_policy(source_fps, shortest, acf);
    let mut out = vec![act.clone(), dp.clone()];
    if point_clouds {
        let mut p = dp;
        p.name = "dp3".into();
        p.preset = "dp3".into();
        p.why.insert(
            0,
            "3D Diffusion Policy: the point clouds unnormalized".into(),
        );
        out.push(p);
    }
    if format != SourceFormat::Lerobot {
        let mut p = act;
        p.name = "lerobot".into();
        p.preset = "lerobot_act".into();
        p.fps = None;
        p.format = Some("parquet".into());
        p.why[0] = format!(
            "a LeRobot v3.0 dataset (LeRobotDataset opens it) at the source rate ({}), K as for ACT",
            fmt_hz(source_fps)
        );
        out.push(p);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_whole_factors() {
        assert_eq!(decimated(30.0, 10.0), 10.0);
        assert_eq!(decimated(50.0, 10.0), 10.0);
        assert_eq!(decimated(15.0, 10.0), 5.0);
        assert_eq!(decimated(5.0, 10.0), 5.0);
        assert_eq!(decimated(12.5, 10.0), 12.5);
    }

    #[test]
    fn k_follows_the_acf_and_the_shortest_episode() {
        let acf = AcfSummary {
            suggested_k: Some(30),
            threshold: 0.3,
            max_lag: 200,
            mean_acf: vec![1.0; 201],
        };
        let p = profiles(SourceFormat::Lerobot, 30.0, 400, Some(&acf), false);
        assert_eq!((p[0].name.as_str(), p[0].chunk), ("act", 30));
        // DP at 10 Hz: 30 source steps are 10 steps, rounded up to 12.
        assert_eq!((p[1].fps, p[1].chunk, p[1].executes), (None, 12, Some(6)));
        assert_eq!(p.len(), 2);
        let p = profiles(SourceFormat::AlohaHdf5, 50.0, 20, Some(&acf), true);
        assert_eq!(p[0].chunk, 20);
        assert_eq!(
            p.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(),
            ["act", "dp", "dp3", "lerobot"]
        );
    }
}
